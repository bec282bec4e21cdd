"""The fleet's per-unit drift test against synthetic recordings tables with known truth: its
false-alarm rate over drift-free fleets, the slope interval's coverage, recalibrations, the crossing
date of a noiseless line, and the reasons given."""

import datetime as dt
import math

import numpy as np
import pyarrow as pa
import pytest
from scipy import stats

from imud.fleet import drift
from drift_tables import EPOCH, NS_PER_DAY, PARAMETERS, SIGMA, column_names, fleet, table, unit_rows


def rows_by_key(units):
    return {(r["unit"], r["parameter"]): r for r in units.drop_columns(
        ["first_utc", "last_utc", "crossing_utc"]).to_pylist()}


def crossing_ns(units, unit, parameter):
    mask = [u == unit and p == parameter for u, p in zip(units["unit"].to_pylist(),
                                                         units["parameter"].to_pylist())]
    value = units.filter(pa.array(mask))["crossing_utc"].cast(pa.int64()).to_pylist()
    assert len(value) == 1
    return value[0]


def test_tolerances_defaults_and_parse():
    t = drift.Tolerances()
    assert (t.accel_bias_m_s2, t.gyro_bias_rad_s, t.scale) == (0.01, 5e-4, 1e-3)
    t = drift.Tolerances.parse("accel-bias=0.02, gyro-bias=1e-3")
    assert (t.accel_bias_m_s2, t.gyro_bias_rad_s, t.scale) == (0.02, 1e-3, 1e-3)
    assert drift.Tolerances.parse("") == drift.Tolerances()
    assert t.for_kind("gyro-bias") == 1e-3
    for text, words in [
        ("gyro=1e-3", "unknown tolerance 'gyro'"),
        ("accel-bias", "not KEY=VALUE"),
        ("scale=big", "'big' is not a number"),
        ("scale=-1", "positive"),
        ("scale=nan", "positive"),
        ("scale=1e-3,scale=2e-3", "given twice"),
    ]:
        with pytest.raises(ValueError, match=words):
            drift.Tolerances.parse(text)


# Turn-on scatter tau as large as the recordings' own sigma (where estimating tau is hardest).
TAU_AS_SIGMA = {p: SIGMA[p.split("_")[0]] for p in PARAMETERS}


@pytest.mark.parametrize("per_unit,tau", [(6, None), (12, TAU_AS_SIGMA)],
                         ids=["6-recordings-tau-2-to-4-sigma", "12-recordings-tau-1-sigma"])
def test_drift_free_fleets_false_alarm_rate_is_at_most_alpha(per_unit, tau):
    # 200 fleets of 8 units x 6 bias parameters over half a year, turn-on scatter tau 2-4x the
    # recordings' own sigma (drift_tables' default) or equal to it: the share of fleets with any
    # unit flagged must not exceed alpha beyond binomial slack (P(X > 8) < 1e-3 for
    # X ~ Bin(200, 0.01)).
    rng = np.random.default_rng(20261128 + per_unit)
    alpha, fleets = 0.01, 200
    any_flag = 0
    p_values = []
    for _ in range(fleets):
        units = drift.analyze_units(fleet(rng, per_unit=per_unit, tau=tau), alpha=alpha)
        assert units.num_rows == 8 * 6
        any_flag += bool(drift.flagged_units(units))
        p_values += units["p_value"].to_pylist()
    assert any_flag <= stats.binom.ppf(0.999, fleets, alpha)
    # The p-values of the null are no smaller than uniform ones: the tails the Bonferroni
    # threshold reaches into are honest (9600 tests; binomial slack of 4 sigma). The test is
    # conservative by design (a unit's own tau^2 when it exceeds its model's pooled one; measured
    # 0.46, 0.067, 0.0035 at 0.5, 0.1, 0.01 with 6 recordings), but not blind: at least a quarter
    # of the nominal share where the tails are wide enough to count.
    p = np.array(p_values)
    for level in (0.5, 0.1, 0.01, 0.001):
        share = (p < level).mean()
        slack = 4 * math.sqrt(level * (1 - level) / p.size)
        assert share <= level + slack, (level, share)
        if level >= 0.01:
            assert share >= level / 4 - slack, (level, share)


def test_slope_interval_covers_the_true_drift():
    # With drift, (r_hat - r) / sigma_r follows t with the test's degrees of freedom (the pooled
    # ones, or n - 2 where a unit's own scatter was larger): the 95 % interval covers the true
    # rate in at least 95 % of the units within binomial slack (4 sigma), and, the test being
    # conservative by design (a unit's own tau^2 when larger), in at most 99 %.
    rng = np.random.default_rng(7)
    truth = {"accel": 1e-5, "gyro": 2e-6}  # per day: 1.8e-3 m/s^2 and 3.6e-4 rad/s over the span
    slopes = {u: {p: truth[p.split("_")[0]] for p in PARAMETERS} for u in range(8)}
    covered = total = 0
    z = []
    for _ in range(100):
        units = drift.analyze_units(fleet(rng, slopes=slopes))
        for row in units.drop_columns(["first_utc", "last_utc", "crossing_utc"]).to_pylist():
            r = truth[row["parameter"].split("_")[0]]
            err = (row["slope_per_day"] - r) / row["slope_std_per_day"]
            covered += abs(err) <= stats.t.ppf(0.975, row["dof"])
            z.append(stats.norm.ppf(stats.t.cdf(err, row["dof"])))
            total += 1
    slack = 4 * math.sqrt(0.95 * 0.05 / total)
    assert 0.95 - slack <= covered / total <= 0.99, covered / total
    # Mapped through its own t distribution the error is centred on 0 (no bias) with a spread
    # of at most 1 (its interval is honest) and not far below (the test is not blind).
    assert abs(np.mean(z)) < 4 / math.sqrt(total)
    assert 0.8 < np.std(z) < 1 + 4 / math.sqrt(2 * total), np.std(z)


def test_drifting_units_flagged_and_rate_recovered():
    rng = np.random.default_rng(3)
    # Unit 2's gyro z walks 3e-5 rad/s per day (1.8e-3 rad/s in two months, beyond the 5e-4
    # tolerance), unit 5's accel x 1e-4 m/s^2 per day; 12 recordings each over 240 days.
    slopes = {2: {"gyro_bias_z": 3e-6}, 5: {"accel_bias_x": 1e-4}}
    units = drift.analyze_units(fleet(rng, per_unit=12, span_days=240, slopes=slopes))
    assert drift.flagged_units(units) == ["GX1 1002", "GX1 1005"]
    rows = rows_by_key(units)
    for (unit, parameter), r in [(("GX1 1002", "gyro_bias_z"), 3e-6), (("GX1 1005", "accel_bias_x"), 1e-4)]:
        row = rows[(unit, parameter)]
        assert row["drifting"] and row["flagged"]
        assert abs(row["slope_per_day"] - r) <= 3 * row["slope_std_per_day"]
        assert "drifting" in row["reason"] and "tolerance" in row["reason"]
    assert sum(r["flagged"] for r in rows.values()) == 2
    assert units.schema.metadata[b"imud.fleet.drift.tests"] == b"48"
    # The reason speaks deg/s for a gyro: 3e-6 rad/s/day * 30 days = 5.2e-3 deg/s.
    assert "deg/s per 30 days" in rows[("GX1 1002", "gyro_bias_z")]["reason"]


def test_recalibration_mid_history_does_not_flag():
    # The true accel x bias holds still at 0.05 m/s^2. The first calibration assumed 0 (5x the
    # tolerance out); on day 100 the unit was recalibrated to 0.05. The estimates are absolute
    # (calibration + offset), so the recalibration is no step, and the band sits around 0.05.
    rng = np.random.default_rng(11)
    days = np.linspace(0, 200, 10)
    cal = np.where(days < 100, 0.0, 0.05)
    rows = unit_rows(rng, "GX1 7", days, offset={"accel_bias_x": 0.05},
                     calibration={"accel_bias_x": cal})
    units = drift.analyze_units(table(rows))
    row = rows_by_key(units)[("GX1 7", "accel_bias_x")]
    assert row["calibration_value"] == 0.05
    assert not row["drifting"] and not row["out_of_tolerance"] and not row["flagged"]
    assert drift.flagged_units(units) == []
    # Before the recalibration the same unit is out of tolerance: the check can fire.
    before = drift.analyze_units(table({k: v[:5] for k, v in rows.items()}))
    row = rows_by_key(before)[("GX1 7", "accel_bias_x")]
    assert row["out_of_tolerance"] and row["flagged"] and row["calibration_value"] == 0.0
    assert "out of tolerance" in row["reason"]


def test_crossing_date_of_a_noiseless_line():
    # gyro z from 0 at day 0 at 1e-5 rad/s per day: leaves 0 +- 5e-4 on day 50 exactly, while the
    # recordings stop at day 30. sigma is tiny and nothing scatters.
    rng = np.random.default_rng(0)
    days = np.linspace(0, 30, 7)
    tiny = {p: 1e-12 for p in PARAMETERS}
    rows = unit_rows(rng, "GX1 1", days, slope_per_day={"gyro_bias_z": 1e-5}, tau={p: 0.0 for p in PARAMETERS},
                     sigma=tiny)
    units = drift.analyze_units(table(rows))
    row = rows_by_key(units)[("GX1 1", "gyro_bias_z")]
    assert row["drifting"] and row["flagged"] and not row["out_of_tolerance"]
    assert row["excess_std"] == 0.0
    assert row["slope_per_day"] == pytest.approx(1e-5, rel=1e-9)
    expected_ns = int((EPOCH + np.timedelta64(50 * NS_PER_DAY, "ns")).astype(np.int64))
    assert abs(crossing_ns(units, "GX1 1", "gyro_bias_z") - expected_ns) <= 10**9
    assert "crosses tolerance 2026-02-20" in row["reason"]
    assert drift.flagged_units(units) == ["GX1 1"]
    # Recalibrated on day 25 to the bias of then (2.5e-4): the band moves with the calibration
    # in force, and the line leaves 2.5e-4 +- 5e-4 on day 75.
    days_r = np.linspace(0, 60, 7)
    recal = unit_rows(rng, "GX1 1", days_r, slope_per_day={"gyro_bias_z": 1e-5},
                      calibration={"gyro_bias_z": np.where(days_r < 25, 0.0, 2.5e-4)},
                      tau={p: 0.0 for p in PARAMETERS}, sigma=tiny)
    units = drift.analyze_units(table(recal))
    row = rows_by_key(units)[("GX1 1", "gyro_bias_z")]
    assert row["calibration_value"] == 2.5e-4 and row["flagged"] and not row["out_of_tolerance"]
    assert abs(crossing_ns(units, "GX1 1", "gyro_bias_z") - expected_ns - 25 * NS_PER_DAY) <= 10**9
    # Downwards from the calibration at 1e-3: the lower edge 0.5e-3 on day 50 again.
    rows = unit_rows(rng, "GX1 1", days, slope_per_day={"gyro_bias_z": -1e-5},
                     offset={"gyro_bias_z": 1e-3}, calibration={"gyro_bias_z": 1e-3},
                     tau={p: 0.0 for p in PARAMETERS}, sigma=tiny)
    units = drift.analyze_units(table(rows))
    assert abs(crossing_ns(units, "GX1 1", "gyro_bias_z") - expected_ns) <= 10**9
    # A horizon shorter than the 20 days left: drifting, no crossing, not flagged.
    units = drift.analyze_units(table(rows), horizon_days=10)
    row = rows_by_key(units)[("GX1 1", "gyro_bias_z")]
    assert row["drifting"] and not row["flagged"]
    assert crossing_ns(units, "GX1 1", "gyro_bias_z") is None
    # Measured from a later "now", 10 days reach it.
    now = dt.datetime(2026, 2, 15, tzinfo=dt.timezone.utc)
    for when in (now, np.datetime64("2026-02-15T00:00:00"),
                 pa.scalar(now, type=pa.timestamp("ns", tz="UTC"))):
        units = drift.analyze_units(table(rows), horizon_days=10, now_utc=when)
        assert abs(crossing_ns(units, "GX1 1", "gyro_bias_z") - expected_ns) <= 10**9
    with pytest.raises(ValueError, match="timezone-aware"):
        drift.analyze_units(table(rows), now_utc=dt.datetime(2026, 2, 15))


def test_too_few_recordings_gives_the_reason():
    rng = np.random.default_rng(5)
    two = unit_rows(rng, "GX1 2", [0, 40])
    same_day = unit_rows(rng, "GX1 3", [10, 10.2, 10.5, 11])
    units = drift.analyze_units(table(two, same_day))
    for row in rows_by_key(units).values():
        assert "too few recordings" in row["reason"], row
        assert row["p_value"] is None and not row["drifting"]
    assert units.schema.metadata[b"imud.fleet.drift.tests"] == b"0"


def test_failed_and_missing_estimates_are_skipped():
    rng = np.random.default_rng(9)
    rows = unit_rows(rng, "GX1 4", np.linspace(0, 90, 8))
    rows["error"] = ["no still window"] + [None] * 7
    value_col, _, _ = column_names("accel_bias_y")
    rows[value_col] = rows[value_col].copy()
    rows[value_col][3] = np.nan
    units = rows_by_key(drift.analyze_units(table(rows)))
    assert units[("GX1 4", "accel_bias_y")]["n"] == 6
    assert units[("GX1 4", "accel_bias_x")]["n"] == 7
    # A unit whose every recording failed still gets its rows, saying so.
    dead = unit_rows(rng, "GX1 5", [0, 10, 20])
    dead["error"] = ["unreadable"] * 3
    units = rows_by_key(drift.analyze_units(table(dead)))
    assert all("no usable recording" in r["reason"] and r["n"] == 0 for r in units.values())


def test_scale_parameters_when_recordings_calibrate_them():
    rng = np.random.default_rng(12)
    days = np.linspace(0, 120, 9)
    rows = unit_rows(rng, "GX1 6", days)
    rows["accel_scale_z"] = 2e-5 * days + rng.normal(0, 5e-5, days.size)
    rows["accel_scale_std_z"] = np.full(days.size, 5e-5)
    units = rows_by_key(drift.analyze_units(table(rows)))
    row = units[("GX1 6", "accel_scale_z")]
    assert row["quantity_unit"] == "1" and row["calibration_value"] == 0.0
    assert abs(row["slope_per_day"] - 2e-5) <= 3 * row["slope_std_per_day"]
    assert row["drifting"] and row["flagged"] and "ppm per 30 days" in row["reason"]
    assert ("GX1 6", "accel_scale_x") not in units  # no recording calibrates it


def test_bad_tables_are_named_and_an_empty_one_is_empty():
    rng = np.random.default_rng(1)
    t = table(unit_rows(rng, "GX1 1", [0, 10, 20]))
    with pytest.raises(ValueError, match="gyro_bias_std_y_rad_s"):
        drift.analyze_units(t.drop_columns(["gyro_bias_std_y_rad_s"]))
    i = t.schema.get_field_index("accel_bias_x_m_s2")
    with pytest.raises(ValueError, match="accel_bias_x_m_s2 is string, not a number"):
        drift.analyze_units(t.set_column(i, "accel_bias_x_m_s2", pa.array(["1", "2", "3"])))
    empty = drift.analyze_units(t.slice(0, 0))
    assert empty.num_rows == 0 and empty.schema.equals(drift.UNITS_SCHEMA)
    assert drift.flagged_units(empty) == []


def test_a_models_units_share_their_scatter_and_a_noisier_unit_keeps_its_own():
    # Eight units of five recordings over half a year: one unit alone has 3 degrees of freedom,
    # and at the fleet's Bonferroni threshold t(3) needs a drift of ~28 sigma over the span. The
    # scatter tau is the model's, so it is estimated from all eight units (about 24 degrees of
    # freedom). Unit 3's gyro z drifts 30 tau over the span; unit 6 scatters 5x more than its
    # siblings on every parameter (it keeps its own tau and n - 2 degrees of freedom, and also
    # inflates the pooled tau, which costs the others some power). Over 40 fleets: pooling calls
    # unit 3's drift far more often than its own evidence alone would, never calls a sibling's
    # noise a drift, and calls unit 6's noise a drift rarely: where its five recordings happen to
    # line up its own tau looks small and the model's is used (the pooling's assumption that one
    # model's units scatter alike; measured 2 of 240 tests at 5x, 1 of 240 at 2x).
    tau = {"accel": 2e-3, "gyro": 1e-4}
    r = 30 * tau["gyro"] / 180.0
    fleets, pooled_hits, alone_hits, noisy_drifts = 40, 0, 0, 0
    for seed in range(fleets):
        rng = np.random.default_rng(seed)
        units_rows = []
        for u in range(8):
            days = np.sort(rng.uniform(0.0, 180.0, 5))
            noisy = {p: 5 * tau[p.split("_")[0]] for p in PARAMETERS} if u == 6 else None
            slope = {"gyro_bias_z": r} if u == 3 else None
            units_rows.append(unit_rows(rng, f"GX1 {1000 + u}", days, slope_per_day=slope, tau=noisy))
        units = drift.analyze_units(table(*units_rows))
        threshold = float(units.schema.metadata[b"imud.fleet.drift.p-threshold"])
        rows = rows_by_key(units)
        row = rows[("GX1 1003", "gyro_bias_z")]
        pooled_hits += row["drifting"]
        if row["drifting"]:
            assert row["dof"] > 3 and abs(row["slope_per_day"] - r) <= 4 * row["slope_std_per_day"]
        t, v, s = drift.unit_points(table(units_rows[3]), "GX1 1003", "gyro_bias_z")[:3]
        alone = drift.fit_drift(t / NS_PER_DAY, v, s)
        assert alone.dof == 3
        alone_hits += alone.p_value < threshold
        for (unit, parameter), other in rows.items():
            if unit == "GX1 1006":
                noisy_drifts += other["drifting"]
            elif (unit, parameter) != ("GX1 1003", "gyro_bias_z"):
                assert not other["drifting"], other
    assert pooled_hits >= 0.7 * fleets and alone_hits <= 0.5 * fleets, (pooled_hits, alone_hits)
    assert noisy_drifts <= 0.02 * fleets * len(PARAMETERS), noisy_drifts
