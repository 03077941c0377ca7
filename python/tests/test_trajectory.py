"""cordis.read_trajectory / write_trajectory: every format, any array layout, clear errors."""

import errno

import numpy as np
import pytest

import cordis
import scenes


@pytest.fixture(scope="module")
def traj():
    return cordis.Scene.from_dict(scenes.damped_chain()).simulate(40)


@pytest.mark.parametrize("ext", ["csv", "npy", "tra"])
def test_round_trip_every_format(tmp_path, traj, ext):
    path = tmp_path / f"chain.{ext}"
    cordis.write_trajectory(path, traj, dt=0.005)
    back = cordis.read_trajectory(path)
    assert back.dtype == np.float64 and back.shape == traj.shape
    assert back.flags.c_contiguous
    # .npy is binary and .csv/.tra print shortest round-trip decimals: all are exact.
    np.testing.assert_array_equal(back, traj)
    assert cordis.read_trajectory(str(path)).shape == traj.shape


def test_npy_is_readable_by_numpy(tmp_path, traj):
    cordis.write_trajectory(tmp_path / "a.npy", traj)
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), traj)
    np.save(tmp_path / "b.npy", traj)
    np.testing.assert_array_equal(cordis.read_trajectory(tmp_path / "b.npy"), traj)


def test_any_layout_and_dtype_is_accepted(tmp_path, traj):
    variants = {
        "fortran": np.asfortranarray(traj),
        "strided": np.stack([traj, traj], axis=-1)[..., 0],  # a non-contiguous view
        "reversed": traj[::-1].copy()[::-1],
        "float32": traj.astype(np.float32),
        "list": traj.tolist(),
    }
    assert not variants["strided"].flags.c_contiguous
    for name, a in variants.items():
        path = tmp_path / f"{name}.npy"
        cordis.write_trajectory(path, a)
        expected = np.asarray(a, dtype=np.float64)
        np.testing.assert_array_equal(cordis.read_trajectory(path), expected, err_msg=name)


def test_integer_positions_are_converted(tmp_path):
    a = np.arange(2 * 3 * 3).reshape(2, 3, 3)
    cordis.write_trajectory(tmp_path / "i.csv", a)
    np.testing.assert_array_equal(cordis.read_trajectory(tmp_path / "i.csv"), a.astype(float))


@pytest.mark.parametrize("shape", [(10, 3), (4, 2, 2), (2, 3, 3, 1), (5,)])
def test_wrong_shape_names_the_expected_one(tmp_path, shape):
    with pytest.raises(ValueError, match=r"\(T, N, 3\).*got shape"):
        cordis.write_trajectory(tmp_path / "x.npy", np.zeros(shape))


def test_non_finite_value_is_a_trajectory_error_naming_the_place(tmp_path, traj):
    bad = traj.copy()
    bad[3, 2, 1] = np.nan
    with pytest.raises(cordis.TrajectoryError) as e:
        cordis.write_trajectory(tmp_path / "x.npy", bad)
    assert e.value.place == "frame 3, particle 2, y"


def test_not_numbers_is_a_type_error(tmp_path):
    with pytest.raises(TypeError, match="array: expected an array of numbers"):
        cordis.write_trajectory(tmp_path / "x.npy", [[["a", "b", "c"]]])


def test_empty_trajectory_is_refused(tmp_path):
    with pytest.raises(cordis.TrajectoryError, match="empty trajectory"):
        cordis.write_trajectory(tmp_path / "x.npy", np.zeros((0, 4, 3)))


def test_bad_dt_is_a_value_error(tmp_path, traj):
    for dt in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="dt: must be a positive number"):
            cordis.write_trajectory(tmp_path / "x.npy", traj, dt=dt)


def test_unknown_extension_is_a_format_error(tmp_path, traj):
    with pytest.raises(cordis.FormatError, match=r"\.csv, \.npy or \.tra"):
        cordis.write_trajectory(tmp_path / "x.txt", traj)
    with pytest.raises(cordis.FormatError):
        cordis.read_trajectory(tmp_path / "x.json")


def test_missing_file_is_an_io_error(tmp_path):
    with pytest.raises(cordis.CordisIOError) as e:
        cordis.read_trajectory(tmp_path / "nope.csv")
    assert isinstance(e.value, OSError) and e.value.errno == errno.ENOENT


def test_malformed_file_is_a_format_or_trajectory_error(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("frame,particle,x,y,z\n0,0,1,2\n")
    with pytest.raises(cordis.CordisError) as e:
        cordis.read_trajectory(path)
    assert "bad.csv" in str(e.value)
