"""Flight plan: the demo file, derived geometry, and clear errors for impossible plans."""
import copy
import math
from pathlib import Path

import pytest
import tomllib

from ins.common.errors import InputError
from ins.simulate.plan_read import load_plan, parse_plan

DEMO = Path(__file__).resolve().parents[1] / "data" / "flights" / "demo.toml"


@pytest.fixture(scope="module")
def demo_dict():
    with open(DEMO, "rb") as f:
        return tomllib.load(f)


def test_demo_loads_in_si(demo_dict):
    plan = load_plan(DEMO)
    b, f = demo_dict["block"], demo_dict["flight"]
    assert plan.block.origin_lat == pytest.approx(math.radians(b["origin_lat_deg"]))
    assert plan.flying_height_m == b["origin_h_m"] + f["height_agl_m"]
    # bank -> turn rate of a coordinated turn: tan(bank) = V r / g
    assert math.tan(math.radians(f["bank_deg"])) == pytest.approx(
        f["ground_speed_mps"] * plan.flight.turn_rate / 9.80665)
    assert plan.source == str(DEMO)


def test_footprint_spacing_interval(demo_dict):
    plan = load_plan(DEMO)
    c, f, b = demo_dict["camera"], demo_dict["flight"], demo_dict["block"]
    scale = f["height_agl_m"] / c["focal_length_mm"]          # image mm -> ground m
    along = c["width_px"] * c["pixel_size_mm"] * scale        # camera x forward (nadir axes)
    across = c["height_px"] * c["pixel_size_mm"] * scale
    assert plan.footprint_along_m == pytest.approx(along)
    assert plan.strip_spacing_m == pytest.approx((1 - b["side_overlap_percent"] / 100) * across)
    assert plan.exposure_interval_s == pytest.approx(
        (1 - b["forward_overlap_percent"] / 100) * along / f["ground_speed_mps"])
    # a camera turned by 90 deg about its axis swaps the image axes along/across track
    d = copy.deepcopy(demo_dict)
    d["camera"]["axes"] = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]
    assert parse_plan(d).footprint_along_m == pytest.approx(
        c["height_px"] * c["pixel_size_mm"] * scale)


def test_explicit_spacing_and_interval(demo_dict):
    d = copy.deepcopy(demo_dict)
    del d["block"]["side_overlap_percent"], d["block"]["forward_overlap_percent"]
    d["block"]["strip_spacing_m"] = 333.0
    d["block"]["exposure_interval_s"] = 4.5
    plan = parse_plan(d)
    assert (plan.strip_spacing_m, plan.exposure_interval_s) == (333.0, 4.5)


@pytest.mark.parametrize("section,key,value,words", [
    ("flight", "height_agl_m", -100.0, "[flight] height_agl_m"),
    ("block", "side_overlap_percent", 100.0, "[block] side_overlap_percent"),
    ("block", "forward_overlap_percent", 120.0, "[block] forward_overlap_percent"),
    ("flight", "bank_deg", 40.0, "[flight] bank_deg"),           # max_bank_deg 30
    ("wind", "speed_mps", 35.0, "azimuth limit"),                 # crab > 30 deg
    ("wind", "speed_mps", 30.0, "the mount cannot follow"),      # crab 25 deg > 80 % of 30
    ("turbulence", "roll_amp_deg", [3.0, 1.5], "[turbulence] roll_amp_deg: the mount cannot"),
    ("turbulence", "pitch_amp_deg", [4.5, 0.1], "[turbulence] pitch_amp_deg"),
    ("flight", "run_in_m", 5.0, "[flight] run_in_m"),            # < 3 servo lags
    ("flight", "colour", "red", "[flight] colour: unknown key"),
    ("turbulence", "roll_freq_hz", [0.1], "[turbulence] roll_freq_hz"),
    ("imu", "grade", "toy", "[imu] grade"),
    ("camera", "axes", [[1, 0, 0], [0, 1, 0], [0, 0, 2]], "[camera] axes"),
    ("gnss", "outages", [[10.0, -1.0]], "[gnss] outages"),
    ("flight", "ground_speed_mps", "fast", "[flight] ground_speed_mps"),
])
def test_impossible_values_name_the_key(tmp_path, demo_dict, section, key, value, words):
    d = copy.deepcopy(demo_dict)
    d[section][key] = value
    path = tmp_path / "bad.toml"
    import tomli_w
    path.write_bytes(tomli_w.dumps(d).encode())
    with pytest.raises(InputError) as exc:
        load_plan(path)
    assert str(exc.value).startswith(f"{path}: ")
    assert words in str(exc.value)


def test_turns_beyond_the_level_limit_are_accepted_up_to_the_max_bank(demo_dict):
    """In the turns the mount saturates: any bank up to [flight] max_bank_deg is fine."""
    d = copy.deepcopy(demo_dict)
    assert d["flight"]["bank_deg"] > d["mount"]["level_limit_deg"]
    del d["flight"]["bank_deg"]
    d["flight"]["turn_rate_deg_s"] = 3.0          # bank atan(60 * 0.0524 / g) = 17.8 deg
    plan = parse_plan(d)
    assert math.degrees(plan.flight.bank) == pytest.approx(
        math.degrees(math.atan(60.0 * math.radians(3.0) / 9.80665)))
    d["flight"]["turn_rate_deg_s"] = 8.0          # 40 deg
    with pytest.raises(InputError, match=r"\[flight\] turn_rate_deg_s: .*max_bank_deg"):
        parse_plan(d)
    d["flight"]["max_bank_deg"] = 45.0
    parse_plan(d)


def test_crab_within_limit_is_accepted_and_unknown_section_refused(demo_dict):
    d = copy.deepcopy(demo_dict)
    d["wind"]["speed_mps"] = 20.0          # crab ~17 deg on the strips: below 80 % of 30 deg
    parse_plan(d)
    d["weather"] = {"rain": True}
    with pytest.raises(InputError, match=r"\[weather\]: unknown section"):
        parse_plan(d)


def test_input_dict_not_modified(demo_dict):
    d = copy.deepcopy(demo_dict)
    parse_plan(d)
    assert d == demo_dict


def test_not_toml(tmp_path):
    path = tmp_path / "x.toml"
    path.write_text("[block\norigin_lat_deg = 1")
    with pytest.raises(InputError, match="not valid TOML"):
        load_plan(path)
