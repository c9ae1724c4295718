"""vibrissa.sweep and vibrissa.ray.sweep against the command line's `vibrissa sweep`."""

import csv
import os
import subprocess

import numpy as np
import pytest

import vibrissa
from test_simulate import cli

GRID = ["d=0.016,0.024", "v=0.4:1.2:3"]


def cli_sweep(out, *grid):
    args = [a for g in grid for a in ("--grid", g)]
    subprocess.run([cli(), "sweep", "e2", "--out", out, *args], check=True, capture_output=True)


def manifest(path):
    """The manifest's rows without the wall time of each run."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    k = rows[0].index("seconds")
    return [r[:k] + r[k + 1:] for r in rows]


def same_folders(a, b):
    names = sorted(os.listdir(a))
    assert names == sorted(os.listdir(b))
    for name in names:
        if name == "manifest.csv":
            assert manifest(a / name) == manifest(b / name)
        else:
            assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    cli_sweep(out, *GRID)
    return out


def test_threads_write_the_command_line_s_files_and_resume(tmp_path, reference):
    summary = vibrissa.sweep("e2", {"d": [0.016, 0.024], "v": "0.4:1.2:3"}, tmp_path, jobs=2)
    assert summary["runs"] == 6 and summary["ran"] == 6 and summary["failed"] == []
    same_folders(tmp_path, reference)
    # A run whose sidecar is missing runs again; the others are skipped.
    (tmp_path / "d0.016_v0.8.json").unlink()
    summary = vibrissa.sweep("e2", GRID, tmp_path)
    assert (summary["ran"], summary["skipped"]) == (1, 5)
    same_folders(tmp_path, reference)


def test_without_a_folder_the_runs_come_back_as_arrays():
    runs = vibrissa.sweep("e2", {"d": [0.016, 0.024], "v": [0.4]})
    assert [r["params"] for r in runs] == [{"d": 0.016, "v": 0.4}, {"d": 0.024, "v": 0.4}]
    assert runs[1]["file"] == "d0.024_v0.4.csv"
    one = vibrissa.simulate("e2", d=0.024, v=0.4)
    for c in vibrissa.COLUMNS:
        np.testing.assert_array_equal(runs[1]["run"][c], one[c])


def test_the_experiment_s_own_grid():
    runs = vibrissa.sweep("e2")
    assert len(runs) == 80 and runs[-1]["params"] == {"d": 0.03, "v": 1.5}


def test_bad_grids_raise_naming_the_grid(tmp_path):
    with pytest.raises(ValueError, match="a range has three parts"):
        vibrissa.sweep("e2", {"d": "0.01:0.02"})
    with pytest.raises(ValueError, match="unknown field `nonsense`"):
        vibrissa.sweep("e2", {"nonsense": [1, 2]}, tmp_path)
    with pytest.raises(TypeError, match="grid"):
        vibrissa.sweep("e2", 3)
    with pytest.raises(ValueError, match="format"):
        vibrissa.sweep("e2", out=tmp_path, format="xlsx")
    with pytest.raises(ValueError, match="no grid given"):
        vibrissa.sweep("examples/scenarios/rat_curved.toml" if os.path.exists(
            "examples/scenarios/rat_curved.toml") else "nonexistent.toml")


def test_failed_runs_are_reported_after_the_others(tmp_path):
    # A whisker too short for the box: runs at d beyond the tip still run; a negative length
    # cannot be simulated.
    with pytest.raises(vibrissa.SweepError) as e:
        vibrissa.sweep("e2", {"whisker.length": [0.03, -0.01]}, tmp_path)
    assert len(e.value.failures) == 1 and "whisker.length=-0.01" in e.value.failures[0][0]
    assert (tmp_path / "whisker.length0.03.csv").is_file()
    assert len(manifest(tmp_path / "manifest.csv")) == 2


@pytest.fixture(scope="module")
def ray():
    if os.environ.get("VIBRISSA_REQUIRE_RAY"):
        import ray
    else:
        ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_writes_the_command_line_s_files_and_resumes(tmp_path, reference, ray):
    import vibrissa.ray

    summary = vibrissa.ray.sweep("e2", GRID, tmp_path, chunk=2)
    assert summary["ran"] == 6
    same_folders(tmp_path, reference)
    (tmp_path / "d0.024_v1.2.csv").unlink()
    summary = vibrissa.ray.sweep("e2", GRID, tmp_path)
    assert (summary["ran"], summary["skipped"]) == (1, 5)
    same_folders(tmp_path, reference)


def test_ray_from_the_shell_entry_point(tmp_path, reference, ray):
    import vibrissa.ray

    argv = ["e2", "--out", str(tmp_path), *[a for g in GRID for a in ("--grid", g)]]
    assert vibrissa.ray.main(argv) == 0
    same_folders(tmp_path, reference)
    assert vibrissa.ray.main(["e2", "--out", str(tmp_path), "--grid", "d=1:2"]) == 1
