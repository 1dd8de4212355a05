"""The cuff: element geometry on the limb, the load cell's frame, the strap's preload, sensor patches.

- :mod:`~phri_spring.physics.cuff.geometry` Element geometry of a cuff (docs/model.md sections 1 and 13)
- :mod:`~phri_spring.physics.cuff.loadcell` Load-cell wrench to cuff-frame wrench (docs/model.md section 5)
- :mod:`~phri_spring.physics.cuff.patches` Free element layouts: sensor patches anywhere on the limb (docs/model.md section 14)
- :mod:`~phri_spring.physics.cuff.preload` Strap pretension (docs/model.md sections 3 and 13)
"""
