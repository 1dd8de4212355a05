"""I/O layer: files and streams in, plain arrays and dataclasses out; outputs written
atomically. Folders:

- :mod:`~phri_spring.io.cache` Caches on disk: the coupled FE's surface stiffness and the hyperelastic reduced models
- :mod:`~phri_spring.io.config` The YAML config of docs/model.md section 6: safe loading and validation
- :mod:`~phri_spring.io.live` Live streams: sources (stdin CSV, ATI Net F/T, LSL), the streamed outputs and the browser dashboard
- :mod:`~phri_spring.io.logs` Wrench logs in, contact forces out (docs/model.md section 7): one import for all three jobs
- :mod:`~phri_spring.io.memory` What a run needs and what the machine can give: the memory budget checked before anything is allocated
- :mod:`~phri_spring.io.outputs` Writing outputs: the forces table (CSV, Parquet) and atomic replacement of any output
- :mod:`~phri_spring.io.recordings` Lab recordings read into arrays: a comparison's experiment (manifest, trial tables) and indenter files
- :mod:`~phri_spring.io.presets` The bundled configs ("presets") and the starter configs ``phri init`` writes from them
- :mod:`~phri_spring.io.scan` 3D limb scans as the cuff's surface: reading the mesh, its unit and frame (docs/scans.md)
"""
