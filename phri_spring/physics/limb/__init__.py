"""Limb shapes: cross-sections and taper, sections and strap handles on a 3D scan.

- :mod:`~phri_spring.physics.limb.bounds` What a limb's shape may be: the bounds of its size and taper (docs/model.md section 13)
- :mod:`~phri_spring.physics.limb.scan_sections` Cuff elements on a triangulated limb surface (a 3D scan), in the cuff frame (docs/scans.md)
- :mod:`~phri_spring.physics.limb.scan_strap` The strap's handles on a scanned limb (docs/scans.md, "Strap handles")
- :mod:`~phri_spring.physics.limb.sections` Limb sections beyond the circle: the outline maths of docs/model.md section 13
"""
