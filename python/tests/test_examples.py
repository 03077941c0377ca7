"""cordis.example and cordis.EXAMPLES."""

import pytest

import cordis


def test_examples_are_the_shipped_names():
    assert cordis.EXAMPLES == (
        "rigid", "cloth", "fluid", "horse", "muscle", "horse-gait", "tadpole", "frog",
        "follower", "central-muscle", "bouncing-ball", "horse-ground",
    )


@pytest.mark.parametrize("name", cordis.EXAMPLES)
def test_every_example_builds_and_has_no_unknowns(name):
    s = cordis.example(name)
    assert s.num_particles > 0 and not s.has_unknowns
    assert cordis.example(name) == s  # deterministic


def test_unknowns_are_boxes_around_the_truth():
    truth = cordis.example("rigid").to_dict()
    boxed = cordis.example("rigid", unknowns=True, width=25.0, seed=3).to_dict()
    n = 0
    for name, t in truth["types"].items():
        for key, value in t.items():
            b = boxed["types"][name][key]
            if isinstance(value, float) and value > 0 and key != "rest_cos":
                assert isinstance(b, dict), (name, key)
                assert b["min"] < value < b["max"]
                assert b["max"] / b["min"] == pytest.approx(25.0)
                n += 1
            else:
                assert b == value
    assert n == 20
    # Another seed puts the truth elsewhere in its box.
    other = cordis.example("rigid", unknowns=True, seed=4).to_dict()
    assert other != boxed
    assert cordis.example("rigid", unknowns=True, seed=3).to_dict() == boxed


def test_width_sets_the_box_ratio():
    d = cordis.example("rigid", unknowns=True, width=4.0).to_dict()
    b = d["types"]["brace"]["stiffness"]
    assert b["max"] / b["min"] == pytest.approx(4.0)


def test_unknown_name_lists_the_names():
    with pytest.raises(ValueError, match="unknown example `tadpol`.*rigid, cloth, fluid, horse, muscle, horse-gait, tadpole, frog"):
        cordis.example("tadpol")


@pytest.mark.parametrize("width", [1.0, 0.5, float("nan"), float("inf"), 1e308])
def test_bad_width_is_a_value_error(width):
    with pytest.raises(ValueError, match="width"):
        cordis.example("rigid", unknowns=True, width=width)


def test_bad_width_is_the_clis_argument_error():
    # One validation for the CLI's --width and this keyword: the same range, the unit named.
    with pytest.raises(cordis.ArgumentError) as e:
        cordis.example("rigid", unknowns=True, width=float("inf"))
    assert e.value.place == "width"
    assert "above 1 and at most 1e100 (the boxes' ratio max/min), got inf" in str(e.value)


def test_tadpole_couplings_round_trip_and_it_swims():
    s = cordis.example("tadpole")
    d = s.to_dict()
    assert d["couplings"] == [{"type": "muscle", "particles": [0, 1]}]
    assert d["signals"]["stroke"]["shape"] == "sawtooth"
    assert cordis.Scene.from_dict(d) == s
    x = s.simulate(4000)
    assert x.mean(axis=1)[-1, 0] - x.mean(axis=1)[0, 0] >= 2.0  # body lengths (1 m)
    # The symmetric control: same amplitude, a triangle.
    d["signals"]["stroke"] = {"shape": "triangle", "amplitude": 3.5, "period": 4.0, "phase": 0.75}
    x = cordis.Scene.from_dict(d).simulate(4000)
    assert abs(x.mean(axis=1)[-1, 0] - x.mean(axis=1)[0, 0]) < 0.2
