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
    assert repr(s) == "Scene(particles=6, types=2, links=5, dt=0.005)"  # no unknowns


def test_equality_pickle_and_copy():
    a = cordis.Scene.from_dict(scenes.gas())
    b = cordis.Scene.from_dict(scenes.gas())
    c = cordis.Scene.from_dict(scenes.gas(seed=3))
    assert a == b and a != c and a != "scene"
    assert pickle.loads(pickle.dumps(a)) == a
    assert copy.copy(a) == a and copy.deepcopy(a) == a
    # Scenes are editable: a copy is independent of its original.
    for c in (copy.copy(a), copy.deepcopy(a), a.copy()):
        c.dt = 2 * a.dt
        assert c != a and a == b


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


def test_an_unbounded_file_is_refused_with_the_limit_not_errno_none(tmp_path):
    # Issue 17: a symlink to /dev/zero was read until memory ran out, then surfaced as
    # `CordisIOError [Errno None] None`.
    zero = tmp_path / "zero.json"
    zero.symlink_to("/dev/zero")
    with pytest.raises(cordis.CordisIOError) as e:
        cordis.Scene.from_json(zero)
    text = str(e.value)
    assert "Errno None" not in text and "None:" not in text, text
    assert text.startswith(f"{zero}: not a regular file, and more than the 268435456 bytes"), text
    assert e.value.place == str(zero)
    traj = tmp_path / "zero.npy"
    traj.symlink_to("/dev/zero")
    with pytest.raises(cordis.CordisIOError, match="256 MiB"):
        cordis.read_trajectory(traj)


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


# --- editing ------------------------------------------------------------------------------


def test_edits_write_through_and_round_trip():
    """Each edit shows in the views, the arrays, to_dict and to_json; the edited scene equals
    the one built from the edited dict."""
    s = cordis.Scene.from_dict(scenes.damped_chain())
    s.dt = 0.002
    s.gravity = np.array([0.0, -1.0, 0.0])
    s.types["soft"]["stiffness"] = 55.0
    s.types["stiff"]["damping"] = np.float32(0.25)
    s.particles[2].mass = 1.5
    s.particles[-1].pos = (1.0, 2.0, 3.0)
    s.particles[1].vel = [0.0, 0.0, 0.5]
    s.particles[3].fixed = True
    want = scenes.damped_chain()
    want["dt"] = 0.002
    want["gravity"] = [0.0, -1.0, 0.0]
    want["types"]["soft"]["stiffness"] = 55.0
    want["types"]["stiff"]["damping"] = 0.25
    want["particles"][2]["mass"] = 1.5
    want["particles"][5]["pos"] = [1.0, 2.0, 3.0]
    want["particles"][1]["vel"] = [0.0, 0.0, 0.5]
    want["particles"][3]["fixed"] = True
    assert s == cordis.Scene.from_dict(want)
    assert cordis.Scene.from_json(s.to_json()) == s
    assert s.to_dict()["types"]["soft"]["stiffness"] == 55.0
    assert (s.dt, s.gravity) == (0.002, (0.0, -1.0, 0.0))
    assert s.masses[2] == 1.5 and s.particles[2].mass == 1.5
    assert s.positions[5].tolist() == [1.0, 2.0, 3.0]
    assert s.particles[3].fixed and not s.particles[4].fixed
    # The simulation follows the edits: the newly fixed particle stays put.
    traj = s.simulate(20)
    assert np.array_equal(traj[:, 3], np.repeat(traj[:1, 3], 20, axis=0))


def test_unknowns_are_settable_and_identifiable():
    truth = cordis.Scene.from_dict(scenes.spring_on_fixed(k=20.0, z=0.3))
    scene = truth.copy()
    assert not scene.has_unknowns
    scene.types["rib"]["stiffness"] = cordis.Unknown(1.0, 100.0)
    scene.types["rib"]["damping"] = {"min": 0.0, "max": 2.0, "init": 1.0}  # the JSON shape
    assert scene.has_unknowns
    u = scene.types["rib"]["stiffness"]
    assert isinstance(u, cordis.Unknown) and (u.min, u.max, u.init) == (1.0, 100.0, None)
    assert u.value == pytest.approx(10.0)  # geometric middle of a box wider than a decade
    assert scene.types["rib"]["damping"] == cordis.Unknown(0.0, 2.0, init=1.0)
    assert scene.to_dict()["types"]["rib"]["stiffness"] == {"min": 1.0, "max": 100.0}
    assert "unknowns=2" in repr(scene)
    res = cordis.identify(scene, truth.simulate(50), truth=truth)
    assert res.param_error_pct < 1e-6
    assert res.scene.types["rib"]["stiffness"] == pytest.approx(20.0, rel=1e-9)
    # And back to known.
    scene.types["rib"]["stiffness"] = 20.0
    scene.types["rib"]["damping"] = 0.3
    assert scene == truth


def test_unknown_masses():
    s = cordis.Scene.from_dict(scenes.damped_chain())
    s.particles[1].mass = cordis.Unknown(0.1, 10.0, init=2.0)
    assert s.particles[1].mass == cordis.Unknown(0.1, 10.0, init=2.0)
    assert s.masses[1] == 2.0  # the starting value
    assert s.to_dict()["particles"][1]["mass"] == {"min": 0.1, "max": 10.0, "init": 2.0}
    with pytest.raises(cordis.SceneError, match=r"particles\[1\]\.mass\.min") as e:
        s.particles[1].mass = cordis.Unknown(-1.0, 1.0)
    assert e.value.place == "particles[1].mass.min"
    assert s.particles[1].mass == cordis.Unknown(0.1, 10.0, init=2.0)  # unchanged


@pytest.mark.parametrize("edit, exc, place", [
    (lambda s: s.types["rib"].__setitem__("stiffness", -1.0), cordis.SceneError,
     "types.rib.stiffness"),
    (lambda s: s.types["rib"].__setitem__("rest_length", float("nan")), cordis.SceneError,
     "types.rib.rest_length"),
    (lambda s: s.types["rib"].__setitem__("stifness", 1.0), cordis.SceneKeyError,
     "types.rib.stifness"),
    (lambda s: s.types["ribs"], cordis.SceneKeyError, "types.ribs"),
    (lambda s: s.particles[1].__setattr__("mass", 0.0), cordis.SceneError,
     "particles[1].mass"),
    (lambda s: s.particles[0].__setattr__("pos", (0.0, float("inf"), 0.0)), cordis.SceneError,
     "particles[0].pos[1]"),
    (lambda s: s.particles[2], cordis.SceneIndexError, "particles[2]"),
    (lambda s: s.particles[-3], cordis.SceneIndexError, "particles[-3]"),
    (lambda s: setattr(s, "dt", 0.0), cordis.SceneError, "dt"),
    (lambda s: setattr(s, "gravity", (0.0, 0.0, float("nan"))), cordis.SceneError,
     "gravity[2]"),
    (lambda s: setattr(s, "masses", np.array([1.0, -2.0])), cordis.SceneError,
     "particles[1].mass"),
])
def test_refused_edits_name_the_place_and_change_nothing(edit, exc, place):
    s = cordis.Scene.from_dict(scenes.spring_on_fixed())
    before = s.to_json()
    with pytest.raises(exc) as e:
        edit(s)
    assert e.value.place == place
    assert place in str(e.value)
    assert isinstance(e.value, cordis.CordisError)
    assert s.to_json() == before


def test_lookup_errors_are_also_builtin_lookup_errors():
    s = cordis.Scene.from_dict(scenes.spring_on_fixed())
    with pytest.raises(KeyError, match="they have: stiffness, rest_length, damping"):
        s.types["rib"]["stifness"]
    with pytest.raises(KeyError, match="the scene has: rib"):
        s.types["nope"]
    with pytest.raises(IndexError, match="the scene has 2 particles"):
        s.particles[5]
    assert s.types.get("nope") is None and s.types["rib"].get("nope", 3) == 3


@pytest.mark.parametrize("edit, exc, words", [
    (lambda s: setattr(s, "dt", "fast"), TypeError, "dt: expected a number, got str"),
    (lambda s: setattr(s, "dt", True), TypeError, "got bool"),
    (lambda s: s.types["rib"].__setitem__("stiffness", "x"), TypeError,
     "types.rib.stiffness: expected a number or cordis.Unknown"),
    (lambda s: s.types["rib"].__setitem__("stiffness", {"min": 1.0}), TypeError,
     "needs \"min\" and \"max\""),
    (lambda s: setattr(s, "gravity", (0.0, 1.0)), ValueError,
     r"gravity: expected an array of shape \(3,\), got shape \(2,\)"),
    (lambda s: setattr(s, "positions", np.zeros((3, 3))), ValueError,
     r"positions: expected an array of shape \(2, 3\), got shape \(3, 3\)"),
    (lambda s: setattr(s, "masses", [1.0]), ValueError, r"masses: .*shape \(2,\)"),
    (lambda s: s.particles[1].__setattr__("fixed", 1), TypeError, "expected a bool"),
    (lambda s: cordis.Unknown(2.0, 1.0), ValueError, r"Unknown: min 2(\.0)? is above max 1"),
    (lambda s: cordis.Unknown(0.0, 1.0, init=3.0), ValueError, "outside"),
])
def test_wrong_values_are_type_or_value_errors(edit, exc, words):
    s = cordis.Scene.from_dict(scenes.spring_on_fixed())
    before = s.to_json()
    with pytest.raises(exc, match=words):
        edit(s)
    assert s.to_json() == before


def test_returned_arrays_are_read_only_copies():
    """Writing into `scene.masses[i]` would silently change a copy: it raises instead."""
    s = cordis.Scene.from_dict(scenes.damped_chain())
    for a in (s.masses, s.positions, s.velocities):
        assert a.dtype == np.float64 and not a.flags["WRITEABLE"]
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1.0
    assert s.positions.shape == (6, 3) and s.velocities.shape == (6, 3)
    x = np.asfortranarray(s.positions + 1.0)  # any layout
    s.positions = x
    assert np.array_equal(s.positions, x)
    s.velocities = np.zeros((6, 3))
    s.masses = np.arange(1, 7)  # ints convert
    assert s.masses.tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]


def test_views_are_mappings_and_sequences():
    d = scenes.damped_chain()
    s = cordis.Scene.from_dict(d)
    soft_links = sum(link["type"] == "soft" for link in d["links"])
    assert list(s.types) == s.type_names == list(s.types.keys())
    assert len(s.types) == 2 and "soft" in s.types and "x" not in s.types
    soft = s.types["soft"]
    assert s.types[0].name == "soft" and s.types[-1].name == "stiff"
    assert (soft.name, soft.kind, soft.num_links) == ("soft", "spring", soft_links)
    assert dict(soft) == {"stiffness": 40.0, "rest_length": 0.8, "damping": 0.4}
    assert dict(soft.items()) == dict(soft) and soft.values() == [40.0, 0.8, 0.4]
    assert len(soft) == 3 and "damping" in soft
    assert [n for n, _ in s.types.items()] == ["soft", "stiff"]
    assert len(s.particles) == 6
    assert [p.index for p in s.particles] == list(range(6))
    assert [p.mass for p in s.particles] == s.masses.tolist()
    assert s.particles[0].fixed and s.particles[0].group is None
    assert repr(soft) == ("LinkType('soft', kind='spring', stiffness=40.0, rest_length=0.8, "
                          "damping=0.4)")
    assert repr(s.particles[0]) == "Particle(0, mass=1.0, pos=(0.0, 0.0, 0.0), fixed=True)"
    # A view outlives nothing: it reads the scene as it is now.
    s.types["soft"]["stiffness"] = 41.0
    assert soft["stiffness"] == 41.0


def test_muscle_weights_are_parameters():
    s = cordis.example("muscle")
    t = next(v for v in s.types.values() if v.kind == "muscle")
    assert "w_len[0]" in t.keys() and "w_rate[0]" in t.keys()
    t["w_len[0]"] = -0.5  # weights may be negative (inhibition)
    assert t["w_len[0]"] == -0.5
    assert s.to_dict()["types"][t.name]["w_len"][0] == -0.5
    with pytest.raises(cordis.SceneError, match=r"gain"):
        t["gain"] = -1.0


def test_str_is_a_readable_summary():
    s = cordis.Scene.from_dict(scenes.damped_chain())
    s.types["stiff"]["stiffness"] = cordis.Unknown(10.0, 1000.0)
    text = str(s)
    assert text.startswith("Scene: 6 particles (1 fixed), 5 links, 2 types; dt = 0.005 s")
    assert "soft" in text and "stiffness=Unknown(10.0, 1000.0)" in text
    assert "(3 links)" in text and "(2 links)" in text
    assert "1 unknown(s) to identify" in text
    assert repr(s) == "Scene(particles=6, types=2, links=5, dt=0.005, unknowns=1)"


def test_unknown_pickles_and_compares():
    u = cordis.Unknown(1.0, 2.0, init=1.5)
    assert pickle.loads(pickle.dumps(u)) == u and u != cordis.Unknown(1.0, 2.0)
    assert u.to_dict() == {"min": 1.0, "max": 2.0, "init": 1.5}
    assert repr(u) == "Unknown(1.0, 2.0, init=1.5)"


def test_edit_during_simulate_does_not_affect_it():
    """simulate runs on a snapshot: an edit made meanwhile from another thread gives either
    the motion before the edit or the one after, never a mixture, and is kept afterwards."""
    s = cordis.Scene.from_dict(scenes.cloth())
    edited = s.copy()
    edited.types[0]["stiffness"] = 1.0
    before, after = s.simulate(3000), edited.simulate(3000)
    result = {}
    t = threading.Thread(target=lambda: result.setdefault("traj", s.simulate(3000)))
    t.start()
    s.types[0]["stiffness"] = 1.0
    t.join()
    assert np.array_equal(result["traj"], before) or np.array_equal(result["traj"], after)
    assert not np.array_equal(before, after)
    assert s == edited


def test_max_elongation_is_settable_on_springs_only():
    cloth = cordis.Scene.from_dict(scenes.cloth(tau=0.05))
    springs = [t for t in cloth.types.values() if t.kind == "spring"]
    assert springs and all(t.max_elongation == 0.05 for t in springs)
    for t in springs:
        t.max_elongation = None
    want = scenes.cloth()
    for t in want["types"].values():
        t.pop("max_elongation", None)
    assert cloth == cordis.Scene.from_dict(want)
    springs[0].max_elongation = 0.1
    assert cloth.to_dict()["types"][springs[0].name]["max_elongation"] == 0.1
    with pytest.raises(cordis.SceneError, match="must be a positive number") as e:
        springs[0].max_elongation = 0.0
    assert e.value.place == f"types.{springs[0].name}.max_elongation"
    assert springs[0].max_elongation == 0.1
    chain = cordis.Scene.from_dict(scenes.anchors())
    other = next(t for t in chain.types.values() if t.kind != "spring")
    with pytest.raises(cordis.SceneError, match="only springs have it"):
        other.max_elongation = 0.1
    assert other.max_elongation is None
