"""cordis.Scene: reading, writing, simulating, and the errors it raises."""

import copy
import errno
import json
import pathlib
import pickle
import threading
import time

import numpy as np
import pytest

import cordis
import scenes


# --- reading and writing ------------------------------------------------------------------


def test_dict_round_trip_is_equal():
    for make in scenes.ALL.values():
        s = cordis.Scene.from_dict(make())
        assert cordis.Scene.from_dict(s.to_dict()) == s


def test_json_round_trip_is_equal_and_matches_to_dict():
    s = cordis.Scene.from_dict(scenes.cloth())
    text = s.to_json()
    assert text.endswith("\n")
    assert cordis.Scene.from_json(text) == s
    assert json.loads(text) == s.to_dict()


def test_to_dict_fills_defaults_and_keeps_catalogue_order():
    d = scenes.spring_on_fixed()
    d["types"] = {"b": {"kind": "drag", "damping": 1.0}, **d["types"]}
    out = cordis.Scene.from_dict(d).to_dict()
    assert out["format"] == "cordis-scene/1"
    assert list(out["types"]) == ["b", "rib"]
    assert out["types"]["rib"]["damping"] == 0.0
    assert out["links"] == [{"type": "rib", "particles": [0, 1]}]
    assert isinstance(out["links"][0]["particles"][0], int)


def test_unknown_parameters_round_trip():
    d = scenes.spring_on_fixed()
    d["types"]["rib"]["stiffness"] = {"min": 1.0, "max": 100.0, "init": 3.0}
    s = cordis.Scene.from_dict(d)
    assert s.has_unknowns
    assert s.to_dict()["types"]["rib"]["stiffness"] == {"min": 1.0, "max": 100.0, "init": 3.0}
    assert not cordis.Scene.from_dict(scenes.spring_on_fixed()).has_unknowns


def test_path_and_text_inputs(tmp_path):
    s = cordis.Scene.from_dict(scenes.angles())
    f = tmp_path / "angles.json"
    f.write_text(s.to_json())
    assert cordis.Scene.from_json(f) == s  # pathlib.Path
    assert cordis.Scene.from_json(str(f)) == s  # str path
    assert cordis.Scene.from_json("  \n\t" + s.to_json()) == s  # text after blanks


def test_from_dict_accepts_numpy_values():
    d = scenes.spring_on_fixed()
    d["particles"][1]["pos"] = np.array([1.5, 0.0, 0.0])
    d["particles"][1]["mass"] = np.float32(2.0)
    d["links"][0]["particles"] = np.array([0, 1], dtype=np.int64)
    d["dt"] = np.float64(0.01)
    assert cordis.Scene.from_dict(d) == cordis.Scene.from_dict(scenes.spring_on_fixed())


def test_properties_and_repr():
    s = cordis.Scene.from_dict(scenes.damped_chain())
    assert (s.num_particles, s.num_links, s.num_types) == (6, 5, 2)
    assert s.type_names == ["soft", "stiff"]
    assert s.dt == 0.005
    assert s.gravity == (0.0, 0.0, -9.81)
    assert repr(s) == "Scene(particles=6, types=2, links=5, dt=0.005)"


def test_equality_pickle_and_copy():
    a = cordis.Scene.from_dict(scenes.gas())
    b = cordis.Scene.from_dict(scenes.gas())
    c = cordis.Scene.from_dict(scenes.gas(seed=3))
    assert a == b and a != c and a != "scene"
    assert pickle.loads(pickle.dumps(a)) == a
    assert copy.copy(a) == a and copy.deepcopy(a) == a


# --- simulating ---------------------------------------------------------------------------


def test_simulate_shape_dtype_contiguity():
    s = cordis.Scene.from_dict(scenes.cloth())
    t = s.simulate(frames=50)
    assert t.shape == (50, 12, 3)
    assert t.dtype == np.float64
    assert t.flags["C_CONTIGUOUS"] and t.flags["WRITEABLE"]
    assert np.isfinite(t).all()
    assert s.simulate(0).shape == (0, 12, 3)
    first = s.simulate(1)
    assert np.array_equal(first[0], [p["pos"] for p in scenes.cloth()["particles"]])


def test_simulate_is_deterministic_and_consistent_across_lengths():
    s = cordis.Scene.from_dict(scenes.jet())
    assert np.array_equal(s.simulate(120)[:80], s.simulate(80))


@pytest.mark.parametrize("z", [0.0, 0.3])
def test_first_step_by_hand(z):
    """Frame 1 = 2 x0 - x(-1) + dt² (F/m + g), with x(-1) = x0 - v0 dt and v(0) = v0."""
    k, l0, m, dt = 20.0, 1.0, 2.0, 0.01
    x0, v0, g = np.array([1.5, 0.0, 0.0]), np.array([0.1, 0.2, 0.0]), np.array([0, 0, -9.81])
    s = cordis.Scene.from_dict(
        scenes.spring_on_fixed(k=k, l0=l0, z=z, m=m, x0=x0, v0=v0, dt=dt, gravity=g)
    )
    traj = s.simulate(2)
    # The fixed particle is at the origin: u from it to the mass is +x, L = 1.5, rate s = v0·u.
    force_on_mass = -(k * (1.5 - l0) + z * v0[0]) * np.array([1.0, 0.0, 0.0])
    want = 2 * x0 - (x0 - v0 * dt) + dt**2 * (force_on_mass / m + g)
    assert np.allclose(traj[1, 1], want, rtol=0, atol=1e-15)
    assert np.array_equal(traj[:, 0], np.zeros((2, 3)))


def test_diverging_scene_raises():
    d = scenes.spring_on_fixed(k=1e7, m=1.0, dt=0.1)
    with pytest.raises(cordis.DivergedError) as e:
        cordis.Scene.from_dict(d).simulate(10_000)
    assert e.value.particle == 1 and e.value.frame > 0
    assert isinstance(e.value, cordis.CordisError)


@pytest.mark.parametrize("frames, exc", [(-1, ValueError), (10**30, ValueError),
                                         (2.5, TypeError), ("10", TypeError)])
def test_bad_frame_counts(frames, exc):
    s = cordis.Scene.from_dict(scenes.spring_on_fixed())
    with pytest.raises(exc, match="frames"):
        s.simulate(frames)


def test_unallocatable_frame_count_is_a_memory_error():
    s = cordis.Scene.from_dict(scenes.cloth())
    with pytest.raises(MemoryError):
        s.simulate(10**15)


def test_simulate_releases_the_gil():
    """Another Python thread keeps running while simulate computes."""
    d = {
        "dt": 0.001,
        "particles": [scenes.particle([0.1 * i, 0, 0], group="g") for i in range(400)],
        "types": {"c": {"kind": "conditional", "stiffness": 1.0, "rest_length": 0.1,
                        "range": 0.35, "groups": ["g"]}},
    }
    s = cordis.Scene.from_dict(d)
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.0005)

    th = threading.Thread(target=tick)
    th.start()
    try:
        time.sleep(0.01)
        start = time.perf_counter()
        s.simulate(3000)
        end = time.perf_counter()
    finally:
        stop.set()
        th.join()
    inside = [t for t in ticks if start < t < end]
    assert end - start > 0.02, "simulate should take long enough to observe"
    assert len(inside) >= 3


# --- errors -------------------------------------------------------------------------------


def test_exception_tree():
    for cls in (cordis.SceneError, cordis.TrajectoryError, cordis.FormatError,
                cordis.DivergedError, cordis.CordisIOError):
        assert issubclass(cls, cordis.CordisError)
        assert cls.__module__ == "cordis"
    assert issubclass(cordis.CordisError, Exception)
    assert issubclass(cordis.CordisIOError, OSError)


def _bad(mutate):
    d = scenes.spring_on_fixed()
    mutate(d)
    return d


@pytest.mark.parametrize(
    "mutate, place, words",
    [
        (lambda d: d["types"]["rib"].update(kind="rope"), "types.rib.kind", "unknown kind"),
        (lambda d: d["links"][0].update(particles=[0, 7]), "links[0].particles[1]",
         "particle 7 does not exist"),
        (lambda d: d["links"][0].update(particles=[1, 1]), "links[0].particles[1]", "itself"),
        (lambda d: d["particles"][1].update(mass=-2.0), "particles[1].mass", "positive"),
        (lambda d: d["types"]["rib"].update(stiffness=-1.0), "types.rib.stiffness",
         "non-negative"),
        (lambda d: d["particles"][0].update(colour="red"), "particles[0].colour", "unknown key"),
        (lambda d: d.pop("dt"), "dt", "missing"),
        (lambda d: d["links"][0].update(type="nope"), "links[0].type", "no type named"),
        (lambda d: d["particles"][1].update(pos=[0, float("nan"), 0]), "particles[1].pos[1]",
         "finite"),
        (lambda d: d["particles"][1].update(pos=[0, 0]), "particles[1].pos", "3 numbers"),
        (lambda d: d["types"]["rib"].update(stiffness=object()), "types.rib.stiffness",
         "expected a JSON value"),
        (lambda d: d["types"].update({3: {"kind": "drag"}}), "types", "keys must be strings"),
        (lambda d: d["particles"][1].update(mass=10**400), "particles[1].mass", "too large"),
    ],
)
def test_malformed_scenes_name_their_place(mutate, place, words):
    d = _bad(mutate)
    with pytest.raises(cordis.SceneError) as e:
        cordis.Scene.from_dict(d)
    assert e.value.place == place
    assert words in str(e.value)
    assert str(e.value).startswith(place + ": ")
    assert "\n" not in str(e.value)


def test_malformed_json_text_is_a_format_error():
    with pytest.raises(cordis.FormatError) as e:
        cordis.Scene.from_json('{"dt": 0.01,\n "particles": [}')
    assert e.value.place.startswith("scene:2:")


def test_json_with_scene_errors_is_a_scene_error():
    d = scenes.spring_on_fixed()
    d["links"][0]["particles"] = [0, 5]
    with pytest.raises(cordis.SceneError, match=r"links\[0\]\.particles\[1\]"):
        cordis.Scene.from_json(json.dumps(d))


def test_empty_file_is_a_format_error(tmp_path):
    f = tmp_path / "empty.json"
    f.write_text("")
    with pytest.raises(cordis.FormatError, match="empty"):
        cordis.Scene.from_json(f)


def test_missing_file_is_an_os_error(tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(OSError) as e:
        cordis.Scene.from_json(missing)
    assert isinstance(e.value, cordis.CordisIOError)
    assert e.value.errno == errno.ENOENT
    assert e.value.filename == str(missing)


def test_wrong_argument_types():
    for bad in (42, b"{}", None):
        with pytest.raises(TypeError, match="path_or_text"):
            cordis.Scene.from_json(bad)
    with pytest.raises(cordis.SceneError, match="expected an object"):
        cordis.Scene.from_dict([1, 2, 3])


def test_self_referencing_dict_does_not_crash():
    d = scenes.spring_on_fixed()
    loop = []
    loop.append(loop)
    d["particles"][0]["pos"] = loop
    with pytest.raises(cordis.SceneError, match="deeper"):
        cordis.Scene.from_dict(d)


def test_package_surface():
    assert cordis.__version__ == "0.1.0" or cordis.__version__.count(".") == 2
    for name in cordis.__all__:
        assert hasattr(cordis, name)
    assert (pathlib.Path(cordis.__file__).parent / "py.typed").exists()


def test_json_text_round_trip_is_bit_exact():
    """Every float survives to_json → from_json unchanged (shortest repr, correctly rounded)."""
    rng = np.random.default_rng(11)
    d = scenes.gas()
    for p in d["particles"]:
        p["pos"] = list(rng.normal(size=3) * 10.0 ** rng.integers(-8, 8))
    a = cordis.Scene.from_dict(d)
    b = cordis.Scene.from_json(a.to_json())
    assert b == a
    assert b.to_dict()["particles"] == a.to_dict()["particles"]
