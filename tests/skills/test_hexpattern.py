import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from atemr.errors import ConfigError, ProtocolError, RegistryError
from atemr.msgs import LaserScan, Pose2D
from atemr.skills.hexpattern import (
    HEX,
    HEX90,
    HEX_LAYOUTS,
    SECTORS,
    BasePoints,
    HexLayout,
    ascii_drawing,
    hex_pattern,
    scan_to_base,
    sectorise,
)

N = 360
INC = math.radians(1.0)
A0 = math.radians(0.5)  # beams at 0.5°, 1.5°, ...: never on a 30° sector boundary


def scan_with(returns: dict[float, float], *, fill: float = math.nan, pose: Pose2D | None = None) -> LaserScan:
    """360 beams at 0.5° + k°; ``returns`` maps beam angle in degrees (x.5) to range."""
    ranges = np.full(N, fill)
    for deg, r in returns.items():
        ranges[round(deg - 0.5) % N] = r
    return LaserScan(0.0, ranges, A0, INC, 0.15, 8.0, pose or Pose2D())


def value(result, sector, field="mean_m"):
    return float(getattr(result, field)[SECTORS.index(sector)])


def test_hand_computed_sector_means_hex90():
    h = hex_pattern(scan_with({30.5: 0.5, 45.5: 0.7, 90.5: 1.0, 330.5: 0.3, 200.5: 2.0}), "hex90")
    assert value(h, "FL") == pytest.approx(0.6)
    assert value(h, "FL", "nearest_m") == pytest.approx(0.5)
    assert value(h, "LC") == pytest.approx(1.0)
    assert value(h, "FR") == pytest.approx(0.3)
    # 2.0 m is outside the 1.2 m radius: not averaged (sector reads the radius), but still the nearest return
    assert value(h, "RR") == pytest.approx(1.2)
    assert value(h, "RR", "nearest_m") == pytest.approx(2.0)
    assert h.count.tolist() == [1, 2, 1, 0, 0, 0]
    for s in ("RL", "RC"):
        assert value(h, s) == 1.2 and value(h, s, "nearest_m") == math.inf
    assert h.as_dict()["FL"] == pytest.approx(0.6)


def test_hex_is_hex90_turned_back_by_90_degrees():
    # straight ahead is HEX's LC face; 60° left is its RL face
    h = hex_pattern(scan_with({0.5: 0.4, 60.5: 0.9, 180.5: 0.5}), "hex")
    assert value(h, "LC") == pytest.approx(0.4)
    assert value(h, "RL") == pytest.approx(0.9)
    assert value(h, "RC") == pytest.approx(0.5)
    assert HEX.span_deg("LC") == (-30.0, 30.0)
    assert HEX90.span_deg("FL") == (0.0, 60.0)
    for s in SECTORS:
        assert HEX90.centre_deg(s) == pytest.approx(((HEX.centre_deg(s) + 90.0 + 180.0) % 360.0) - 180.0)


def test_invalid_returns_dropped_and_minus_inf_is_an_obstacle_at_min_range():
    returns = {10.5: math.nan, 20.5: 0.0, 30.5: math.inf, 40.5: 0.1, 50.5: 9.0, 55.5: -math.inf, 5.5: 0.8}
    h = hex_pattern(scan_with(returns), "hex90")
    # FL keeps 0.8 and -inf→0.15 only
    assert value(h, "FL") == pytest.approx((0.8 + 0.15) / 2)
    assert value(h, "FL", "nearest_m") == pytest.approx(0.15)
    assert h.count.sum() == 2


def test_sensor_pose_moves_points_to_the_base_frame():
    # a lidar 0.2 m ahead of the base centre, mounted facing backwards: its beam at 0.5° points behind
    pose = Pose2D(0.2, 0.0, math.pi)
    h = hex_pattern(scan_with({0.5: 0.7}, pose=pose), "hex90")
    # point at x = 0.2 - 0.7 = -0.5 (slightly right of -x): 0.5 m from the base origin, in RR
    assert value(h, "RR") == pytest.approx(0.5, abs=1e-4)
    pts = scan_to_base(scan_with({0.5: 0.7}, pose=pose))
    assert pts.range_m[0] == pytest.approx(0.5, abs=1e-4)


def test_empty_scan_reads_clear():
    h = hex_pattern(LaserScan(0.0, np.array([]), 0.0, INC, 0.15, 8.0), "hex")
    assert np.all(h.mean_m == 1.2) and np.all(np.isinf(h.nearest_m)) and h.count.sum() == 0
    assert h.nearest_by_direction() == (math.inf, math.inf, math.inf)


def test_nearest_by_direction_from_sector_geometry():
    h90 = hex_pattern(scan_with({10.5: 0.9, 300.5: 0.8, 90.5: 0.3, 230.5: 0.6}), "hex90")
    assert h90.nearest_by_direction() == pytest.approx((0.8, 0.6, 0.3))
    # HEX: only the face straight ahead is front, only the one behind is rear
    h = hex_pattern(scan_with({0.5: 0.9, 45.5: 0.4, 180.5: 0.7}), "hex")
    assert h.nearest_by_direction() == pytest.approx((0.9, 0.7, 0.4))


@pytest.mark.parametrize(
    ("change", "what"),
    [
        ({"ranges_m": np.zeros((2, 3))}, "one-dimensional"),
        ({"angle_increment_rad": math.nan}, "angle_increment_rad"),
        ({"angle_increment_rad": 0.0}, "angle_increment_rad is 0"),
        ({"range_min_m": 9.0}, "range_min_m <= range_max_m"),
        ({"sensor_pose": Pose2D(math.inf, 0, 0)}, "sensor_pose.x_m"),
    ],
)
def test_malformed_scans_raise_protocol_error_naming_the_field(change, what):
    base = {"t": 1.0, "ranges_m": np.ones(4), "angle_min_rad": 0.0, "angle_increment_rad": INC,
            "range_min_m": 0.15, "range_max_m": 8.0}
    base.update(change)
    with pytest.raises(ProtocolError, match=what):
        hex_pattern(LaserScan(**base))


def test_bad_radius_and_unknown_layout():
    s = scan_with({})
    with pytest.raises(ProtocolError, match="radius_m"):
        hex_pattern(s, radius_m=-1.0)
    with pytest.raises(RegistryError, match="did you mean 'hex90'"):
        hex_pattern(s, "hex9")


def test_layout_definitions_are_checked():
    with pytest.raises(ConfigError, match="once each"):
        HexLayout("bad", ("FR", "FR", "LC", "RL", "RR", "RC"), (0, 60, 120, 180, 240, 300), "test")
    with pytest.raises(ConfigError, match="span 360"):
        HexLayout("bad", HEX90.order, (0, 60, 50, 180, 240, 300), "test")


@pytest.mark.parametrize("name", list(HEX_LAYOUTS))
def test_every_registered_layout_covers_the_circle_and_draws(name):
    layout = HEX_LAYOUTS.get(name)
    total = sum(layout.span_deg(s)[1] - layout.span_deg(s)[0] for s in SECTORS)
    assert total == pytest.approx(360.0)
    assert layout.source
    drawing = ascii_drawing(name)
    assert "^^" in drawing and all(s in drawing for s in SECTORS)


# ---- property tests ---------------------------------------------------------------------------------

ranges_st = st.lists(
    st.one_of(
        st.floats(0.0, 10.0),
        st.sampled_from([math.nan, math.inf, -math.inf, 0.0]),
    ),
    min_size=N,
    max_size=N,
)


def loop_reference(ranges, layout, radius):
    """The straightforward per-beam version (sensor at the base origin) to compare against."""
    sums = dict.fromkeys(SECTORS, 0.0)
    counts = dict.fromkeys(SECTORS, 0)
    for i, raw in enumerate(ranges):
        r = 0.15 if raw == -math.inf else raw
        if not (math.isfinite(r) and r > 0 and 0.15 <= r <= 8.0) or r > radius:
            continue
        deg = math.degrees(A0 + i * INC)
        for s in SECTORS:
            lo, hi = layout.span_deg(s)
            if (deg - lo) % 360.0 < hi - lo:
                sums[s] += r
                counts[s] += 1
    return [sums[s] / counts[s] if counts[s] else radius for s in SECTORS], [counts[s] for s in SECTORS]


@settings(max_examples=40, deadline=None)
@given(ranges=ranges_st, layout=st.sampled_from([HEX, HEX90]), radius=st.floats(0.3, 3.0))
def test_matches_a_per_beam_loop(ranges, layout, radius):
    # A return exactly at the radius is in or out by one ulp of the base-frame range (hypot of the transformed
    # point): no meaningful boundary to compare at.
    assume(all(abs(r - radius) > 1e-9 for r in ranges if math.isfinite(r)))
    h = hex_pattern(LaserScan(0.0, np.array(ranges), A0, INC, 0.15, 8.0), layout, radius)
    means, counts = loop_reference(ranges, layout, radius)
    assert h.count.tolist() == counts
    np.testing.assert_allclose(h.mean_m, means, rtol=1e-12)
    assert np.all(h.mean_m <= radius + 1e-12)
    has = h.count > 0
    assert np.all(h.nearest_m[has] <= h.mean_m[has] + 1e-12)


@settings(max_examples=40, deadline=None)
@given(ranges=ranges_st)
def test_hex_of_a_scan_equals_hex90_of_the_scan_turned_90_degrees(ranges):
    # turning the sensor moves points by one rounding error: keep returns off the 1.2 m radius edge
    ranges = [math.nan if abs(r - 1.2) < 1e-9 else r for r in ranges]
    a = hex_pattern(LaserScan(0.0, np.array(ranges), A0, INC, 0.15, 8.0), HEX)
    turned = LaserScan(0.0, np.array(ranges), A0, INC, 0.15, 8.0, Pose2D(0.0, 0.0, math.pi / 2))
    b = hex_pattern(turned, HEX90)
    np.testing.assert_allclose(a.mean_m, b.mean_m, rtol=1e-9)
    assert a.count.tolist() == b.count.tolist()


@settings(max_examples=40, deadline=None)
@given(ranges=st.lists(st.floats(0.2, 7.0), min_size=N, max_size=N),
       junk=st.lists(st.tuples(st.integers(0, N - 1), st.sampled_from([math.nan, math.inf, 0.0, 9.5, 0.01]))))
def test_invalid_returns_are_the_same_as_no_return(ranges, junk):
    clean = np.array(ranges)
    dirty = clean.copy()
    dropped = clean.copy()
    for i, bad in junk:
        dirty[i] = bad
        dropped[i] = math.nan
    a = hex_pattern(LaserScan(0.0, dirty, A0, INC, 0.15, 8.0))
    b = hex_pattern(LaserScan(0.0, dropped, A0, INC, 0.15, 8.0))
    np.testing.assert_array_equal(a.mean_m, b.mean_m)
    np.testing.assert_array_equal(a.nearest_m, b.nearest_m)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), layout=st.sampled_from([HEX, HEX90]), radius=st.floats(0.3, 3.0))
def test_the_compiled_sectors_are_the_numpy_ones_to_the_bit(seed, layout, radius, numpy_baselines):
    """`sectorise`'s one compiled pass gives the nearest, count and mean of every sector with the bits of the numpy
    version it replaced (`benchmarks/numpy_baselines.py`): bearings on sector edges and on the wrap, ranges at the
    radius, NaN bearings and ranges, no points."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 500))
    bearing = rng.uniform(-math.pi, math.pi, n)
    edges = np.radians(np.asarray(layout.starts_deg, dtype=np.float64))
    bearing[: n // 10] = rng.choice(np.concatenate([edges, edges - 2 * math.pi, [math.pi, -math.pi]]), n // 10)
    range_m = rng.uniform(0.01, 6.0, n)
    range_m[n // 10: n // 5] = radius
    if seed % 4 == 0 and n:
        bearing[-1], range_m[0] = math.nan, math.nan
    points = BasePoints(range_m, bearing)
    with np.errstate(invalid="ignore"):  # numpy's minimum warns of a NaN range
        got, want = sectorise(points, layout, radius), numpy_baselines.numpy_sectorise(points, layout, radius)
    for field in ("mean_m", "nearest_m", "count"):
        assert getattr(got, field).tobytes() == getattr(want, field).tobytes(), field
        assert getattr(got, field).dtype == getattr(want, field).dtype
