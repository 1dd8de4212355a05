"""report.md of ``phri design``: the study, the best design, the Pareto table, the figures.

The markdown only; :func:`phri_spring.workflows.design.study.write_outputs` writes it.
Its footnote defines every objective from the objectives table
(:func:`phri_spring.objectives.objectives_footnote`).
"""

from __future__ import annotations

import math

import numpy as np

from ...io.config.study import Parameter
from ...objectives import OBJECTIVES, objectives_footnote

__all__ = ["design_report"]


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(f):
        return "-"
    return f"{f:.4g}"


def _md_table(df) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for _, row in df.iterrows():
        lines.append("| " + " | ".join(_fmt(row[c]) for c in cols) + " |")
    return "\n".join(lines)


def design_report(result, figs: list) -> str:
    """report.md of a design study.

    Parameters
    ----------
    result : StudyResult
        What :func:`phri_spring.workflows.design.study.run_study` produced (its
        ``study``, ``table``, ``best``, ``loads``, ``resumed_batches``,
        ``total_batches`` and ``uncertainty``).
    figs : list of (file name, caption)
        The figures written next to it.
    """
    st = result.study
    t = result.table
    n = len(t)
    lines = [f"# Design study{': ' + st.name if st.name else ''}", ""]
    lines.append(f"- base config: `{st.config.name}`; arm model: {st.arm}")
    if getattr(result, "tissue_law", ""):
        lines.append(f"- tissue law ({st.arm} arm): {result.tissue_law}")
    lines.append(f"- load set: {', '.join(f'`{f.name}`' for f in st.loads)}: "
                 f"{result.loads.n_samples:,} samples, {len(result.loads.weights):,} distinct "
                 + ("(identical rows merged, exact)" if result.loads.tolerance == (0.0, 0.0) else
                    f"(rows merged within {result.loads.tolerance[0]:g} N / "
                    f"{result.loads.tolerance[1]:g} N*m: approximate)"))
    plan = st.plan if st.plan == "grid" else f"{st.plan}:{st.n_samples} (seed {st.seed})"
    lines.append(f"- plan: {plan}, {n} designs; varied: "
                 + ", ".join(f"`{p.path}` ({_param_text(p)})" for p in st.parameters))
    obj = ", ".join(("minimise " if s > 0 else "maximise ") + f"`{o}`"
                    for o, s in zip(st.objectives, st.senses))
    lines.append(f"- objectives: {obj}")
    if st.constraints:
        lines.append("- constraints: " + ", ".join(f"`{c}`" for c in st.constraints))
    nf, npar = int(t["feasible"].sum()), int(t["pareto"].sum())
    lines.append(f"- feasible designs: {nf} of {n}; Pareto-optimal (non-dominated among the "
                 f"feasible): {npar}")
    if result.resumed_batches:
        lines.append(f"- resumed: {result.resumed_batches} of {result.total_batches} batches "
                     "came from an earlier, interrupted run")
    lines.append("")
    lines.append("## Best design")
    lines.append("")
    if result.best < 0:
        lines.append("No design is feasible: relax the constraints or widen the ranges. "
                     "`best.yaml` was not written.")
    else:
        b = t.iloc[result.best]
        lines.append(f"Design {result.best} (the lowest `{st.best}` among the Pareto designs), "
                     "written as a complete config to `best.yaml`, ready for `phri simulate`:")
        lines.append("")
        keep = [p.path for p in st.parameters] + [o for o in OBJECTIVES if o in t.columns]
        lines.append(_md_table(t.loc[[result.best], ["design"] + keep]))
        r = float(b["peak_pressure_to_pain_threshold"])
        if math.isfinite(r):
            verdict = "stays under" if r < 1 else "exceeds"
            lines.append("")
            lines.append(f"Its peak pressure {verdict} the pain threshold "
                         f"({100 * r:.0f}% of it at the worst sample).")
    lines.append("")
    lines.append("## Pareto designs")
    lines.append("")
    par = t[t["pareto"]]
    cols = ["design"] + [p.path for p in st.parameters] + list(st.objectives)
    lines.append(_md_table(par[cols].head(50)) if len(par) else "(none)")
    if len(par) > 50:
        lines.append(f"\n({len(par) - 50} more in designs.csv)")
    if result.uncertainty is not None:
        lines.append("")
        lines.append(result.uncertainty["markdown"])
    if figs:
        lines.append("")
        lines.append("## Figures")
        lines.append("")
        for name, caption in figs:
            lines.append(f"![{caption}]({name})")
            lines.append("")
    lines.append("")
    lines.append(objectives_footnote() + " Parameters of kind `scale` are factors on the base "
                 "config's values. See docs/design.md.")
    return "\n".join(lines) + "\n"


def _param_text(p: Parameter) -> str:
    if p.kind == "range":
        return f"{'log ' if p.log else ''}range {p.low:g}..{p.high:g}"
    return f"{p.kind} {', '.join(f'{v:g}' for v in p.levels)}"
