"""A study's summary: per grid cell, the runs, failures, success rate and the mean and quantiles
of every numeric figure, read back from ``runs.csv`` (so a resumed study is summarised whole);
written to ``summary.csv``, printed as a table, and plotted where the study names a plot
(a work-precision chart for model × step size, a success heat-map for two parameters).
"""
import csv
import math
import os

import numpy as np

from .spec import figure_columns


def _float(text):
    try:
        return float(text)
    except ValueError:
        return math.nan


def figures_summarised(study):
    """The numeric figures summarised per cell: the recorded ones (not ``success``) and ``cost``."""
    return [f for f in figure_columns(study) if f != "success"] + ["cost"]


def qname(q):
    """The column suffix of quantile ``q``: 0.05 → ``q05``, 0.5 → ``q50``, 0.999 → ``q99.9``."""
    p = round(q * 100, 6)
    return f"q{int(p):02d}" if p == int(p) else f"q{p:g}"


def summarise(study, runs_csv, out, stream=None):
    """Summary rows (dicts) of ``runs_csv``, one per grid cell present, in cell order; writes
    ``out/summary.csv``, prints the table to ``stream`` (unless None/False) and writes
    ``out/plot.png`` when the study has a plot and matplotlib is installed."""
    figs = figures_summarised(study)
    axes = [a[0] for a in study.axes]
    cells = {}
    with open(runs_csv, newline="") as fh:
        for row in csv.DictReader(fh):
            c = cells.get(row["cell"])
            if c is None:
                c = cells[row["cell"]] = {"labels": [row[a] for a in axes], "runs": 0, "failed": 0, "success": [],
                                          "values": {f: [] for f in figs}}
            c["runs"] += 1
            if row["exception"]:
                c["failed"] += 1
                continue
            if study.success is not None:
                c["success"].append(_float(row["success"]))
            for f in figs:
                c["values"][f].append(_float(row[f]))
    qs = study.summary["quantiles"]
    rows = []
    for cell in sorted(cells, key=int):
        c = cells[cell]
        r = {"cell": int(cell), **dict(zip(axes, c["labels"])), "runs": c["runs"], "failed": c["failed"]}
        if study.success is not None:
            r["success_rate"] = float(np.mean(c["success"])) if c["success"] else math.nan
        for f in figs:
            v = np.array(c["values"][f], float)
            v = v[np.isfinite(v)]
            r[f"{f}_mean"] = float(v.mean()) if v.size else math.nan
            for q in qs:
                r[f"{f}_{qname(q)}"] = float(np.quantile(v, q)) if v.size else math.nan
        rows.append(r)
    cols = ["cell"] + axes + ["runs", "failed"] + (["success_rate"] if study.success is not None else []) + \
        [f"{f}_{s}" for f in figs for s in ["mean"] + [qname(q) for q in qs]]
    with open(os.path.join(out, "summary.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([repr(r[c]) if isinstance(r[c], float) else r[c] for c in cols])
    if stream:
        print_table(study, rows, stream)
    if study.plot is not None and rows:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            pass
        else:
            path = plot(study, rows, os.path.join(out, "plot.png"))
            if stream:
                print(f"plot written to {path}", file=stream)
    return rows


def print_table(study, rows, stream):
    """The summary as a text table: the cell's values, runs, failed, success rate and the means of
    the figures in ``summary.show`` (default: the first three recorded and ``cost``)."""
    figs = figures_summarised(study)
    show = study.summary["show"] or (figs[:-1][:3] + ["cost"])
    head = [a[0] for a in study.axes] + ["runs", "failed"] + (["success"] if study.success is not None else []) + \
        [f"{f} mean" for f in show]
    body = []
    for r in rows:
        line = [str(r[a[0]]) for a in study.axes] + [str(r["runs"]), str(r["failed"])]
        if study.success is not None:
            line.append(f"{r['success_rate']:.3f}")
        line += [f"{r.get(f + '_mean', math.nan):.4g}" for f in show]
        body.append(line)
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    print("  ".join(h.rjust(w) for h, w in zip(head, widths)), file=stream)
    for b in body:
        print("  ".join(x.rjust(w) for x, w in zip(b, widths)), file=stream)


def short(label, reciprocal=False):
    """A grid value for a chart: four significant digits (with ``reciprocal``, ``1/n`` for the
    reciprocal of a whole number: a step size), or the text."""
    try:
        x = float(label)
    except (TypeError, ValueError):
        return str(label)
    if reciprocal and 0 < x < 1 and abs(1 / x - round(1 / x)) < 1e-9 * (1 / x):
        return f"1/{round(1 / x)}"
    return f"{x:.4g}"


def plot(study, rows, path):
    """``work_precision``: ``y`` against ``x`` (cell means, log-log), one line per value of the
    ``series`` axis through the values of the ``points`` axis (bench_accuracy's chart).
    ``heatmap``: ``value`` (``success_rate`` or ``FIGURE_mean``) over the ``x`` × ``y`` axes, one
    panel per combination of the other axes. Returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p = study.plot
    labels = {a[0]: [str(x) for x in a[1]] for a in study.axes}
    if p["type"] == "work_precision":
        fig, ax = plt.subplots(figsize=(7.5, 5))
        xs, ys = f"{p['x']}_mean", f"{p['y']}_mean"
        for s in labels[p["series"]]:
            rs = [r for r in rows if str(r[p["series"]]) == s and r.get(xs, math.nan) > 0]
            if not rs:
                continue
            x = [r[xs] for r in rs]
            y = [max(r.get(ys, math.nan), 1e-16) for r in rs]
            ax.loglog(x, y, marker="o", label=s)
            for xi, yi, r in zip(x, y, rs):
                ax.annotate(short(r[p["points"]], reciprocal=True), (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=6)
        ax.set_xlabel(f"{p['x']} (mean per cell)")
        ax.set_ylabel(f"{p['y']} (mean per cell; below 1e-16 drawn at 1e-16)")
        ax.set_title(f"{study.name}: {study.description}"[:100], fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_lines():
            ax.legend(fontsize=7)
    else:
        others = [a for a in labels if a not in (p["x"], p["y"])]
        combos = sorted({tuple(str(r[a]) for a in others) for r in rows}, key=lambda c: [
            labels[a].index(v) for a, v in zip(others, c)])
        fig, axs = plt.subplots(1, len(combos), figsize=(4.2 * len(combos), 3.8), squeeze=False)
        value = p["value"]
        for ax, combo in zip(axs[0], combos):
            grid = np.full((len(labels[p["y"]]), len(labels[p["x"]])), np.nan)
            for r in rows:
                if tuple(str(r[a]) for a in others) == combo:
                    grid[labels[p["y"]].index(str(r[p["y"]])), labels[p["x"]].index(str(r[p["x"]]))] = \
                        r.get(value, math.nan)
            im = ax.imshow(grid, origin="lower", cmap="viridis", aspect="auto",
                           vmin=0 if value == "success_rate" else None, vmax=1 if value == "success_rate" else None)
            ax.set_xticks(range(len(labels[p["x"]])), [short(x) for x in labels[p["x"]]], fontsize=7)
            ax.set_yticks(range(len(labels[p["y"]])), [short(y) for y in labels[p["y"]]], fontsize=7)
            ax.set_xlabel(p["x"], fontsize=8)
            ax.set_ylabel(p["y"], fontsize=8)
            ax.set_title(", ".join(f"{a} = {short(v)}" for a, v in zip(others, combo)) or value, fontsize=8)
            for (i, j), v in np.ndenumerate(grid):
                if np.isfinite(v):
                    light = im.norm(v) > 0.5 if np.isfinite(im.norm(v)) else False
                    ax.text(j, i, f"{v:.2g}", ha="center", va="center", fontsize=7, color="k" if light else "w")
        fig.colorbar(im, ax=list(axs[0]), label=value)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)
    return path
