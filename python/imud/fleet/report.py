"""The fleet's HTML report: one self-contained file (no scripts, no external resources; plots are
inline SVG drawn by matplotlib) saying which units to recalibrate and why, with a plot per flagged
parameter, every unit x parameter at a glance, and the recordings that gave no evidence."""

from __future__ import annotations

import datetime as _dt
import io
import math
import os
from typing import Sequence

import jinja2
import markupsafe
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from matplotlib import dates as mdates
from matplotlib import rc_context
from matplotlib.figure import Figure

from . import drift
from .inputs import resolve

__all__ = ["write_report", "render_report"]

_NS_PER_DAY = 86_400 * 1_000_000_000


def write_report(
    path,
    recordings: pa.Table,
    units: pa.Table,
    flagged: Sequence[str],
    title: str = "imud fleet report",
    *,
    filesystem=None,
) -> None:
    """Writes the report to ``path``: a local path, or a URI pyarrow opens (``s3://...``), or a
    path on ``filesystem`` (a ``pyarrow.fs.FileSystem``)."""
    html = render_report(recordings, units, flagged, title=title).encode("utf-8")
    filesystem, path, _ = resolve(os.fspath(path), filesystem)
    with filesystem.open_output_stream(path) as out:
        out.write(html)


def render_report(recordings: pa.Table, units: pa.Table, flagged: Sequence[str],
                  title: str = "imud fleet report") -> str:
    """The report's HTML text (see :func:`write_report`)."""
    rows = _rows(units)
    flagged = list(flagged)
    by_unit: dict = {}
    for row in rows:
        by_unit.setdefault(row["unit"], []).append(row)
    # Most urgent first: already out of tolerance, then by the earliest crossing date.
    flagged.sort(key=lambda u: (_urgency(by_unit.get(u, [])), u))
    evidence = drift.Evidence(recordings) if flagged else None
    figures = []
    recalibrate = []
    for unit in flagged:
        unit_rows = [r for r in by_unit.get(unit, []) if r["flagged"]]
        recalibrate.append({"unit": unit, "reasons": [r["reason"] for r in unit_rows]})
        plots = []
        for row in unit_rows:
            svg = _plot(evidence, row, salt=f"imud-fleet-{len(figures)}-{len(plots)}")
            plots.append({"svg": markupsafe.Markup(svg), "reason": row["reason"],
                          "parameter": row["parameter"]})
        figures.append({"unit": unit, "plots": plots})
    parameters = [p.name for p in drift.PARAMETERS if any(r["parameter"] == p.name for r in rows)]
    grid = []
    for unit in sorted(by_unit):
        cells = {r["parameter"]: _cell(r) for r in by_unit[unit]}
        grid.append({"unit": unit, "flagged": unit in flagged,
                     "cells": [cells.get(p) for p in parameters]})
    headers = []
    for name in parameters:
        spec = drift.spec_of(name)
        _, shown = drift.display_scale(spec.quantity_unit)
        headers.append({"label": spec.label, "unit": f"{shown} / 30 d"})
    meta = units.schema.metadata or {}
    def number(key):
        raw = meta.get(b"imud.fleet.drift." + key)
        return None if raw is None else drift.short(float(raw))

    # The test's settings travel in the units table's metadata (analyze_units); a table whose
    # metadata was replaced still says how many tests the threshold was shared over.
    test = {"alpha": number(b"alpha"), "threshold": number(b"p-threshold"),
            "horizon": number(b"horizon-days"),
            "tests": sum(1 for r in rows if r["p_value"] is not None)}
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)
    return env.from_string(_TEMPLATE).render(
        title=title,
        summary=_summary(recordings, by_unit),
        recalibrate=recalibrate,
        figures=figures,
        headers=headers,
        grid=grid,
        failures=_failures(recordings),
        test=test,
        fmt_p=drift._fmt_p,
    )


def _rows(units: pa.Table) -> list:
    """The units table as dicts, timestamps as int ns (no pandas needed for ns precision)."""
    table = units
    for name in ("first_utc", "last_utc", "crossing_utc"):
        table = table.set_column(table.schema.get_field_index(name), name,
                                 pc.cast(table.column(name), pa.int64()))
    return table.to_pylist()


def _urgency(rows) -> float:
    flagged = [r for r in rows if r["flagged"]]
    if any(r["out_of_tolerance"] for r in flagged):
        return -math.inf
    crossings = [r["crossing_utc"] for r in flagged if r["crossing_utc"] is not None]
    return min(crossings) if crossings else math.inf


def _date(ns) -> str:
    if ns is None:
        return "-"
    return _dt.datetime.fromtimestamp(ns / 1e9, tz=_dt.timezone.utc).strftime("%Y-%m-%d")


def _cell(row) -> dict:
    spec = drift.spec_of(row["parameter"])
    factor, _ = drift.display_scale(spec.quantity_unit)
    if row["flagged"]:
        state = "out of tolerance" if row["out_of_tolerance"] else "crosses " + _date(row["crossing_utc"])
        css = "flag"
    elif row["drifting"]:
        state, css = "drifting", "drift"
    elif row["p_value"] is None:
        state, css = ("no data" if row["n"] == 0 else f"{row['n']} rec."), "few"
    else:
        state, css = "no drift", "ok"
    slope = None if row["slope_per_day"] is None else f"{row['slope_per_day'] * 30 * factor:+.2g}"
    p = None if row["p_value"] is None else drift._fmt_p(row["p_value"])
    return {"slope": slope, "p": p, "state": state, "css": css, "reason": row["reason"]}


def _column(table: pa.Table, name: str):
    return table.column(name) if name in table.column_names else None


def _summary(recordings: pa.Table, by_unit: dict) -> list:
    """(label, value) lines of the fleet's summary."""
    n = recordings.num_rows
    lines = [("Units", str(len(by_unit))), ("Recordings", str(n))]
    start = _column(recordings, "start_utc")
    if start is not None and n:
        ns = pc.cast(start, pa.int64())
        first, last = pc.min(ns).as_py(), pc.max(ns).as_py()
        if first is not None:
            lines.append(("Span", f"{_date(first)} to {_date(last)} "
                                  f"({(last - first) / _NS_PER_DAY:.0f} days)"))
    duration = _column(recordings, "duration_s")
    if duration is not None:
        lines.append(("Recorded", f"{(pc.sum(duration).as_py() or 0.0) / 3600:.1f} h"))
    samples, missing = _column(recordings, "samples"), _column(recordings, "missing_samples")
    if samples is not None and missing is not None:
        total, lost = pc.sum(samples).as_py() or 0, pc.sum(missing).as_py() or 0
        share = 100.0 * lost / (total + lost) if total + lost else 0.0
        lines.append(("Samples lost", f"{lost:,} of {total + lost:,} ({share:.3g} %)"))
    stopped = _column(recordings, "stopped_early")
    if stopped is not None:
        lines.append(("Stopped early", str(n - stopped.null_count)))
    error = _column(recordings, "error")
    if error is not None:
        lines.append(("No evidence (errors)", str(n - error.null_count)))
    return lines


def _failures(recordings: pa.Table) -> list:
    error = _column(recordings, "error")
    if error is None:
        return []
    failed = recordings.filter(pc.is_valid(error))
    out = []
    for i in range(failed.num_rows):
        def get(name):
            col = _column(failed, name)
            return None if col is None else col[i]
        start = get("start_utc")
        start_ns = None if start is None or not start.is_valid else start.cast(pa.int64()).as_py()
        out.append({
            "path": get("path").as_py() if get("path") is not None else "",
            "unit": get("unit").as_py() if get("unit") is not None else "",
            "start": _date(start_ns),
            "error": get("error").as_py(),
        })
    return out


def _plot(evidence: "drift.Evidence", row: dict, salt: str) -> str:
    """One flagged parameter of one unit over time, as an SVG element."""
    spec = drift.spec_of(row["parameter"])
    start_ns, v, s, cal = evidence.unit_points(row["unit"], row["parameter"])
    factor, shown = drift.display_scale(spec.quantity_unit)
    # Scale errors in parts per million, gyro biases in deg/s.
    ylabel = f"{spec.label} ({shown.replace('^2', '²')})"

    def y(x):
        return np.asarray(x, dtype=float) * factor

    def when(ns):
        return np.asarray(ns, dtype=np.int64).astype("datetime64[ns]")

    with rc_context({"svg.hashsalt": salt, "svg.fonttype": "path", "font.size": 10}):
        fig = Figure(figsize=(8.0, 3.8), layout="constrained")
        ax = fig.add_subplot()
        end_ns = int(start_ns[-1])
        if row["crossing_utc"] is not None:
            end_ns = max(end_ns, row["crossing_utc"])
        span_ns = max(end_ns - int(start_ns[0]), _NS_PER_DAY)
        grid_ns = np.linspace(int(start_ns[0]) - 0.03 * span_ns, end_ns + 0.05 * span_ns, 200)
        cal_now, tol = row["calibration_value"], row["tolerance"]
        if cal_now is not None:
            ax.axhspan(y(cal_now - tol), y(cal_now + tol), color="#2e7d32", alpha=0.08, lw=0)
            ax.axhline(y(cal_now), color="#2e7d32", lw=1.2, label="calibration in force")
            for edge in (cal_now - tol, cal_now + tol):
                ax.axhline(y(edge), color="#2e7d32", lw=1.0, ls="--")
            ax.plot([], [], color="#2e7d32", lw=1.0, ls="--",
                    label=f"tolerance ±{drift.short(tol * factor)} {shown}")
        if np.any(np.isfinite(cal)) and np.nanmax(cal) - np.nanmin(cal) > 0:
            ax.step(when(start_ns), y(cal), where="post", color="#888888", lw=1.0,
                    label="calibration per recording")
        if row["slope_per_day"] is not None:
            # The line the table's test drew: its scatter and degrees of freedom.
            fit = drift.fit_drift(start_ns / _NS_PER_DAY, v, s, tau2=row["excess_std"] ** 2,
                                  dof=row["dof"])
            value, std = fit.value_at(grid_ns / _NS_PER_DAY)
            half = fit.t_quantile(0.95) * std
            ax.fill_between(when(grid_ns), y(value - half), y(value + half), color="#1565c0",
                            alpha=0.15, lw=0, label="95 % band of the line")
            inside = grid_ns <= start_ns[-1]
            ax.plot(when(grid_ns[inside]), y(value[inside]), color="#1565c0", lw=1.6,
                    label=f"fit {fit.slope_per_day * 30 * factor:+.3g} {shown} / 30 d")
            ax.plot(when(grid_ns[~inside]), y(value[~inside]), color="#1565c0", lw=1.6, ls=":")
        ax.errorbar(when(start_ns), y(v), yerr=s * factor, fmt="o", ms=4, color="#212121",
                    ecolor="#616161", elinewidth=1, capsize=2, label="recording ± 1σ", zorder=3)
        # The vertical range follows the evidence, the line and the tolerance band; the line's
        # 95 % band may run off it (with few recordings t(n-2) makes it many sigma wide).
        shown_y = [y(v - s), y(v + s)]
        if cal_now is not None:
            shown_y.append(y([cal_now - tol, cal_now + tol]))
        if row["slope_per_day"] is not None:
            shown_y.append(y(value))
        low, high = min(float(np.min(a)) for a in shown_y), max(float(np.max(a)) for a in shown_y)
        pad = 0.08 * (high - low) if high > low else 1.0
        ax.set_ylim(low - pad, high + pad)
        if row["crossing_utc"] is not None:
            ax.axvline(when(row["crossing_utc"]), color="#c62828", lw=1.4, ls="-.")
            verb = "crossed" if row["crossing_utc"] <= start_ns[-1] else "crosses"
            # The label on the side of the line with room for it: left of a crossing in the
            # plot's right half, right of one in its left half (never over the axis).
            x0, x1 = (float(v) for v in mdates.date2num([when(grid_ns[0]), when(grid_ns[-1])]))
            left_half = float(mdates.date2num(when(row["crossing_utc"]))) < (x0 + x1) / 2
            ax.annotate(f"{verb} {_date(row['crossing_utc'])}", xy=(when(row["crossing_utc"]), 1.0),
                        xycoords=("data", "axes fraction"), xytext=(4 if left_half else -4, -4),
                        textcoords="offset points", ha="left" if left_half else "right",
                        va="top", color="#c62828",
                        bbox={"boxstyle": "square,pad=0.15", "fc": "white", "ec": "none",
                              "alpha": 0.8})
        locator = mdates.AutoDateLocator(minticks=4, maxticks=9)
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
        ax.set_xlabel("recording date (UTC)")
        ax.set_ylabel(ylabel)
        ax.grid(True, color="#dddddd", lw=0.6)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize=9, frameon=False)
        buf = io.StringIO()
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg"):]


_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{{ title }}</title>
<style>
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 72em; padding: 0 1em;
       color: #212121; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { font-size: 1.3em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.1em; margin-bottom: 0.3em; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { border: 1px solid #ddd; padding: 0.25em 0.5em; text-align: left; vertical-align: top; }
th { background: #f5f5f5; }
dl.summary { display: grid; grid-template-columns: max-content auto; gap: 0.2em 1.2em; }
dl.summary dt { font-weight: 600; } dl.summary dd { margin: 0; }
figure { margin: 0.5em 0 1.5em 0; } figcaption { font-size: 0.95em; }
svg { max-width: 100%; height: auto; }
td.flag { background: #ffebee; } td.drift { background: #fff8e1; } td.ok { background: #f1f8e9; }
td.few { background: #fafafa; color: #757575; }
td.name { white-space: nowrap; }
td.cell { white-space: nowrap; font-variant-numeric: tabular-nums; }
.small { font-size: 0.85em; color: #616161; }
.overview { overflow-x: auto; }
</style>
</head>
<body>
<h1>{{ title }}</h1>
<dl class="summary">
{% for label, value in summary %}<dt>{{ label }}</dt><dd>{{ value }}</dd>
{% endfor %}</dl>
<p class="small">Drift test per unit and parameter: weighted straight line through the recordings'
estimates, allowing for scatter between recordings beyond their own uncertainties (Paule-Mandel,
shared by the units of one model unless a unit's own is larger), t test of the slope. A slope is drifting when its p-value is below
{% if test.threshold %}{{ test.threshold }} (alpha {{ test.alpha }} shared over the fleet's
{{ test.tests }} tests){% else %}alpha shared over the fleet's {{ test.tests }} tests{% endif %};
a unit is flagged when a drifting line leaves the calibration's tolerance
{% if test.horizon %}within {{ test.horizon }} days{% else %}within the horizon{% endif %},
or lies outside it at its last recording.</p>

<h2>Units to recalibrate ({{ recalibrate | length }})</h2>
{% if recalibrate %}<table>
<tr><th>Unit</th><th>Why</th></tr>
{% for item in recalibrate %}<tr><td class="name"><a href="#unit-{{ loop.index }}">{{ item.unit }}</a></td>
<td>{% for reason in item.reasons %}{{ reason }}{% if not loop.last %}<br>{% endif %}{% endfor %}</td></tr>
{% endfor %}</table>
{% else %}<p>None: every unit's calibration holds.</p>
{% endif %}

{% for figure in figures %}<section class="unit" id="unit-{{ loop.index }}">
<h3>{{ figure.unit }}</h3>
{% for plot in figure.plots %}<figure class="plot" data-parameter="{{ plot.parameter }}">
{{ plot.svg }}
<figcaption>{{ plot.reason }}</figcaption>
</figure>
{% endfor %}</section>
{% endfor %}

<h2>All units</h2>
<div class="overview"><table>
<tr><th>Unit</th>{% for h in headers %}<th>{{ h.label }}<br><span class="small">{{ h.unit }}</span></th>{% endfor %}</tr>
{% for line in grid %}<tr><td>{% if line.flagged %}<strong>{{ line.unit }}</strong>{% else %}{{ line.unit }}{% endif %}</td>
{% for c in line.cells %}{% if c %}<td class="cell {{ c.css }}" title="{{ c.reason }}">{% if c.slope %}{{ c.slope }} <span class="small">p {{ c.p }}</span><br>{% endif %}{{ c.state }}</td>{% else %}<td class="cell few">-</td>{% endif %}{% endfor %}</tr>
{% endfor %}</table></div>

<h2>Recordings with errors ({{ failures | length }})</h2>
{% if failures %}<table>
<tr><th>Recording</th><th>Unit</th><th>Started (UTC)</th><th>Error</th></tr>
{% for f in failures %}<tr><td>{{ f.path }}</td><td>{{ f.unit }}</td><td>{{ f.start }}</td><td>{{ f.error }}</td></tr>
{% endfor %}</table>
{% else %}<p>None.</p>
{% endif %}
</body>
</html>
"""
