"""vibrissa.simulate against the command line's output, and its errors."""

import csv
import math
import os
import pathlib
import subprocess

import numpy as np
import pytest

import vibrissa

ROOT = pathlib.Path(__file__).resolve().parents[3]


def cli():
    """The command-line binary built by `cargo build --release` (or $VIBRISSA_BIN)."""
    path = pathlib.Path(os.environ.get("VIBRISSA_BIN", ROOT / "target" / "release" / "vibrissa"))
    assert path.is_file(), f"{path}: build the command line first (cargo build --release)"
    return path


def cli_columns(tmp_path, *args):
    out = tmp_path / "run.csv"
    subprocess.run([cli(), "simulate", *args, "--out", out], check=True, capture_output=True)
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    header, values = rows[0], rows[1:]
    return {name: np.array([float(r[k]) for r in values]) for k, name in enumerate(header)}


def same_bits(a, b):
    return a.shape == b.shape and all(
        (x == y) or (math.isnan(x) and math.isnan(y)) for x, y in zip(a.tolist(), b.tolist())
    )


@pytest.mark.parametrize(
    "args, keys",
    [
        (["e2"], {}),
        (["e2", "--set", "d=0.023", "--set", "v=0.9"], {"d": 0.023, "v": 0.9}),
        (["e1", "--set", "whisker.length=0.04"], {"whisker__length": 0.04}),
    ],
)
def test_columns_equal_the_command_line_s_to_the_last_digit(tmp_path, args, keys):
    ours = vibrissa.simulate(args[0], **keys)
    theirs = cli_columns(tmp_path, *args)
    assert list(ours) == list(vibrissa.COLUMNS) == list(theirs)
    for name in vibrissa.COLUMNS:
        assert ours[name].dtype == np.float64
        assert same_bits(ours[name], theirs[name]), name


def test_a_scenario_file_and_a_mapping_of_overrides(tmp_path):
    path = ROOT / "examples" / "scenarios" / "e2_d23_v06.toml"
    a = vibrissa.simulate(path, overrides={"v": 1.2})
    b = vibrissa.simulate(str(path), v=1.2)
    assert same_bits(a["theta12"], b["theta12"])
    c = vibrissa.simulate(path)
    assert not same_bits(a["theta12"], c["theta12"])


def test_a_data_frame_when_asked():
    pandas = pytest.importorskip("pandas")
    frame = vibrissa.simulate("e2", as_frame=True)
    assert isinstance(frame, pandas.DataFrame)
    assert list(frame.columns) == list(vibrissa.COLUMNS)
    assert len(frame) == 151
    assert frame["contact"].max() == 1.0


def test_builtins_are_the_seed_experiments():
    assert vibrissa.builtins() == ["e1", "e2"]


@pytest.mark.parametrize(
    "call, error, words",
    [
        (lambda: vibrissa.simulate("e3"), ValueError, ["e3"]),
        (lambda: vibrissa.simulate("e2", whisker__lenght=0.04), ValueError, ["lenght"]),
        (lambda: vibrissa.simulate("e2", d=-0.01), ValueError, ["d"]),
        (lambda: vibrissa.simulate("e2", d=float("nan")), ValueError, ["d", "finite"]),
        (lambda: vibrissa.simulate("e2", d=[1, None]), TypeError, ["d[1]"]),
        (lambda: vibrissa.simulate("e2", overrides=[("d", 0.02)]), TypeError, ["overrides"]),
        (lambda: vibrissa.simulate(20), TypeError, ["scenario"]),
        (lambda: vibrissa.simulate("e2", sample_rate=2e6), ValueError, ["sample_rate"]),
    ],
)
def test_bad_input_raises_an_exception_that_names_it(call, error, words):
    with pytest.raises(error) as e:
        call()
    for w in words:
        assert w in str(e.value), str(e.value)


def test_a_scenario_given_as_a_dict():
    given = {"experiment": "e2", "d": 0.023, "v": 0.9, "whisker": {"preset": "w30"}}
    a = vibrissa.simulate(given)
    b = vibrissa.simulate("e2", d=0.023, v=0.9)
    for name in vibrissa.COLUMNS:
        assert same_bits(a[name], b[name]), name
    # Tables may come before plain keys; overrides apply on top.
    peg = {
        "whisker": {"preset": "w30"},
        "duration": 0.05,
        "objects": [{"shape": "circle", "radius": 0.001, "position": [0.02, 0.003],
                     "velocity": [0.0, -0.1]}],
    }
    run = vibrissa.simulate(peg, duration=0.02)
    assert len(run["t"]) == 21 and run["contact"].max() == 1.0


@pytest.mark.parametrize(
    "given, error, words",
    [
        ({"d": float("nan")}, ValueError, ["finite"]),
        ({"whisker": {"lenght": 0.04}}, ValueError, ["lenght"]),
        ({"duration": None}, ValueError, ["scenario dict"]),
        ({"duration": object()}, TypeError, ["scenario"]),
    ],
)
def test_bad_scenario_dicts_raise_an_exception_that_names_them(given, error, words):
    with pytest.raises(error) as e:
        vibrissa.simulate(given)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_whole_numbers_stay_whole(tmp_path):
    # An integer key (segments) takes a Python int as the command line takes `--set segments=10`.
    mine = vibrissa.simulate("e2", segments=10)
    theirs = cli_columns(tmp_path, "e2", "--set", "segments=10")
    assert all(same_bits(mine[c], theirs[c]) for c in vibrissa.COLUMNS)


def test_an_array_of_whiskers_gives_each_whisker_s_columns(tmp_path):
    example = str(ROOT / "examples" / "scenarios" / "array_row.toml")
    mine = vibrissa.simulate(example)
    theirs = cli_columns(tmp_path, example)
    assert list(mine) == list(theirs)
    assert list(mine)[:3] == ["t", "c1.theta01", "c1.theta12"] and "c3.s" in mine
    assert all(same_bits(mine[c], theirs[c]) for c in mine)
