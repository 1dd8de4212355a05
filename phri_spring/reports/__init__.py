"""Reports: matplotlib ``Figure`` objects (no pyplot state) and markdown tables.

- :mod:`~phri_spring.reports.compare` Figures and the report of phri compare
- :mod:`~phri_spring.reports.design` Figures and the report of phri design
- :mod:`~phri_spring.reports.uncertainty` Figures and report sections of uncertainty bands
- :mod:`~phri_spring.reports.agg_text` An Agg canvas that draws text faster, with the same pixels: laid-out strings and glyphs cached
- :mod:`~phri_spring.reports.figure_base` Shared pieces of the report figures: style, arm colours, the reused-figure renderer base
- :mod:`~phri_spring.reports.indenter_figures` Figures of the indenter analysis (paper Fig. 6), as ``matplotlib.figure.Figure`` objects
- :mod:`~phri_spring.reports.indenter_qlv_figures` Figures of the QLV indenter fit, as ``matplotlib.figure.Figure`` objects (no pyplot)
- :mod:`~phri_spring.reports.layout_figures` Figures of a free element layout (``cuff.patches``, docs/model.md section 14)
- :mod:`~phri_spring.reports.section_figures` The pressure around the limb, section by section (``phri simulate --plot``'s second figure)
- :mod:`~phri_spring.reports.simulate_figures` Figure of ``phri simulate --plot``: a whole log at a glance, as a matplotlib ``Figure``
- :mod:`~phri_spring.reports.stiffness_curves_figure` Figure of ``phri stiffness --curves``: the cuff's force-displacement curves at the load cell
- :mod:`~phri_spring.reports.tissue_law_text` Which tissue law an arm ran, as the short text every summary line and report shows
- :mod:`~phri_spring.reports.tolerance_figure` The exposure figure of ``phri simulate --plot`` with a tolerance curve (docs/tolerance.md)
"""
