"""Contact that slides: Coulomb friction along the loading path (the interface's form, its states, the events, the normal response).

- :mod:`~phri_spring.physics.friction.events` The samples where something slips, lifts off or comes back (docs/model.md section 12)
- :mod:`~phri_spring.physics.friction.form` The interface in compliance form and the state of a loading path (docs/model.md
- :mod:`~phri_spring.physics.friction.normal` Friction on the spring arms with a nonlinear tissue law (docs/model.md section 12.6)
- :mod:`~phri_spring.physics.friction.path` Coulomb friction at the cuff-skin interface: contact that lets go and slides
- :mod:`~phri_spring.physics.friction.states` The three states of an element or patch under Coulomb contact (docs/model.md section 12.1)
"""
