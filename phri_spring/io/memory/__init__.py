"""What a run needs and what the machine can give: the memory budget checked before anything is allocated.

- :mod:`~phri_spring.io.memory.budget` The memory a run needs, estimated from its config before anything is allocated
- :mod:`~phri_spring.io.memory.machine` What the machine can still give a run: the memory figure :mod:`.memory_budget` checks against
"""
