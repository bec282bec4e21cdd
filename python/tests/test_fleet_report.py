"""The fleet's HTML report: well-formed, one plot per flagged parameter, every text escaped, and
written through a pyarrow filesystem as well as to a local path."""

from html.parser import HTMLParser

import numpy as np
import pyarrow as pa

from imud.fleet import drift, report
from drift_tables import fleet, table, unit_rows

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source",
        "track", "wbr"}


class Checker(HTMLParser):
    """Checks that every element is closed in order and counts the plots and their figures."""

    def __init__(self):
        super().__init__()
        self.stack, self.errors = [], []
        self.figures, self.svgs, self.scripts = [], 0, 0

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "figure" and attrs.get("class") == "plot":
            self.figures.append({"parameter": attrs.get("data-parameter"), "svgs": 0})
        if tag == "svg":
            self.svgs += 1
            if self.figures and "figure" in self.stack:
                self.figures[-1]["svgs"] += 1
        if tag == "script":
            self.scripts += 1
        if tag not in VOID:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:]} at {self.getpos()}")
            return
        self.stack.pop()


def sample(rng, bad_name="GX1 <script>alert('x')</script> & co"):
    """Two drifting units (one under a hostile name, drifting in two parameters), one failure."""
    slopes = {1: {"gyro_bias_z": 4e-6}, 4: {"accel_bias_x": 1e-4, "accel_bias_z": -1e-4}}
    recordings = fleet(rng, n_units=6, per_unit=12, span_days=240, slopes=slopes)
    names = recordings["unit"].to_pylist()
    names = [bad_name if u == "GX1 1004" else u for u in names]
    recordings = recordings.set_column(recordings.schema.get_field_index("unit"), "unit",
                                       pa.array(names))
    errors = recordings["error"].to_pylist()
    errors[0] = "no still window <2 s>"
    return recordings.set_column(recordings.schema.get_field_index("error"), "error",
                                 pa.array(errors, pa.string()))


def test_report_parses_and_plots_each_flagged_parameter(tmp_path):
    rng = np.random.default_rng(42)
    bad = "GX1 <script>alert('x')</script> & co"
    recordings = sample(rng, bad)
    units = drift.analyze_units(recordings)
    flagged = drift.flagged_units(units)
    assert sorted(flagged) == sorted(["GX1 1001", bad])
    flagged_rows = [(r["unit"], r["parameter"]) for r in
                    units.drop_columns(["first_utc", "last_utc", "crossing_utc"]).to_pylist()
                    if r["flagged"]]
    assert len(flagged_rows) == 3
    out = tmp_path / "fleet.html"
    report.write_report(out, recordings, units, flagged, title="Fleet <A&B>")
    html = out.read_text(encoding="utf-8")
    checker = Checker()
    checker.feed(html)
    checker.close()
    assert checker.errors == [] and checker.stack == []
    # One figure per flagged parameter, each holding one plot; no other plots.
    assert sorted(f["parameter"] for f in checker.figures) == sorted(p for _, p in flagged_rows)
    assert all(f["svgs"] == 1 for f in checker.figures)
    assert checker.svgs == len(flagged_rows)
    # Every name and message is escaped: nothing a browser would run.
    assert checker.scripts == 0
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "Fleet &lt;A&amp;B&gt;" in html
    assert "no still window &lt;2 s&gt;" in html
    # The plotted unit's reason is in the report, as the units table gives it.
    for r in units.drop_columns(["first_utc", "last_utc", "crossing_utc"]).to_pylist():
        if r["flagged"]:
            assert report.markupsafe.escape(r["reason"]) in html


def test_report_without_flags_and_through_a_pyarrow_filesystem(tmp_path):
    rng = np.random.default_rng(8)
    recordings = table(unit_rows(rng, "GX1 9", np.linspace(0, 60, 5)))
    units = drift.analyze_units(recordings)
    assert drift.flagged_units(units) == []
    report.write_report(f"file://{tmp_path}/quiet.html", recordings, units, [])
    html = (tmp_path / "quiet.html").read_text(encoding="utf-8")
    assert "None: every unit's calibration holds." in html
    assert "<svg" not in html
    checker = Checker()
    checker.feed(html)
    assert checker.errors == [] and checker.stack == []


def test_report_of_a_units_table_without_its_metadata(tmp_path):
    # A units table cast to another schema loses analyze_units' metadata; the report still says
    # how many tests the threshold was shared over.
    rng = np.random.default_rng(4)
    recordings = sample(rng)
    units = drift.analyze_units(recordings).replace_schema_metadata(None)
    html = report.render_report(recordings, units, drift.flagged_units(units))
    assert "alpha shared over the fleet's 36 tests" in html
    # An empty fleet still gives a page.
    empty = recordings.slice(0, 0)
    html = report.render_report(empty, drift.analyze_units(empty), [])
    assert "<dt>Recordings</dt><dd>0</dd>" in html
