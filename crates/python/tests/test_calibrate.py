"""vibrissa.calibrate against the command line's `vibrissa calibrate`, and its errors."""

import json
import subprocess

import pytest

import vibrissa
from test_filter import write_csv
from test_simulate import cli


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """Two e1 strikes of a whisker stiffer than the nominal's (E = 3.4 GPa, not 3.0)."""
    folder = tmp_path_factory.mktemp("labelled")
    rows = ["file,d"]
    for k, d in enumerate([0.017, 0.026]):
        write_csv(folder / f"r{k}.csv", vibrissa.simulate("e1", d=d, whisker__youngs_modulus=3.4e9))
        rows.append(f"r{k}.csv,{d}")
    (folder / "truth.csv").write_text("\n".join(rows) + "\n")
    return folder


def test_the_fit_and_the_fitted_file_are_the_command_line_s(labelled, tmp_path, capsys):
    mine = vibrissa.calibrate("e1", labelled, out=tmp_path / "py.toml")
    out = subprocess.run(
        [cli(), "calibrate", "--scenario", "e1", "--labelled", labelled, "--out",
         tmp_path / "cli.toml", "--json"],
        check=True, capture_output=True, text=True,
    )
    theirs = json.loads(out.stdout)
    assert mine["parameters"] == theirs["parameters"]
    assert mine["channels"] == theirs["channels"]
    assert mine["other_minima"] == theirs["other_minima"]
    assert mine["correlation"] == theirs["correlation"]
    determined = [p["key"] for p in mine["parameters"] if p["determined"]]
    assert mine["correlation"]["keys"] == determined
    assert (tmp_path / "py.toml").read_text() == (tmp_path / "cli.toml").read_text()
    assert mine["scenario"] == (tmp_path / "py.toml").read_text()
    modulus = next(p for p in mine["parameters"] if p["key"] == "whisker.youngs_modulus")
    assert modulus["determined"] and modulus["value"] > 3.0e9
    # The fitted file is a scenario every function takes.
    est = vibrissa.estimate(labelled / "r0.csv", tmp_path / "py.toml", method="krr-local",
                            noise="none", verbose=True)
    assert abs(est["d"]["mean"] - 0.017) < 1e-3
    # It trains on whiskers drawn from the correlations the fitted file records.
    assert "drawn from the fit's standard errors and correlations" in capsys.readouterr().err
    # Fed sample by sample, the filter on a calibrated file draws what calibration left
    # uncertain, as estimate does, and keeps estimate's particle count there (its intervals
    # need them), where on a nominal file it takes a real-time count.
    from test_filter import NOISE
    run = vibrissa.simulate("e1", d=0.02)
    first = {c: run[c][0] for c in vibrissa.CHANNELS}
    drawn = vibrissa.Filter(tmp_path / "py.toml", noise=NOISE)
    assert drawn.particles == 4000
    assert "whisker.youngs_modulus" in drawn.update(run["t"][0], first)
    exact = vibrissa.Filter(tmp_path / "py.toml", noise=NOISE, randomise=False)
    assert exact.particles == 1000
    assert "whisker.youngs_modulus" not in exact.update(run["t"][0], first)


def test_bad_input_raises_and_writes_nothing(labelled, tmp_path):
    with pytest.raises(ValueError, match="ending in .toml"):
        vibrissa.calibrate("e1", labelled, out=tmp_path / "fitted.txt")
    with pytest.raises(ValueError, match="truth.csv"):
        vibrissa.calibrate("e1", tmp_path, out=tmp_path / "fitted.toml")
    with pytest.raises(ValueError, match="did not converge"):
        vibrissa.calibrate("e1", labelled, out=tmp_path / "fitted.toml", max_iterations=1)
    assert not (tmp_path / "fitted.toml").exists()
    with pytest.raises(ValueError, match="max_iterations = 0"):
        vibrissa.calibrate("e1", labelled, max_iterations=0)
    with pytest.raises(ValueError, match="finalists = 0"):
        vibrissa.calibrate("e1", labelled, finalists=0)
    with pytest.raises(TypeError, match="labelled"):
        vibrissa.calibrate("e1", 3)


def test_a_channel_that_recorded_nothing_is_left_out_with_a_warning(tmp_path):
    rows = ["file,d"]
    for k, d in enumerate([0.017, 0.026]):
        run = vibrissa.simulate("e1", d=d, whisker__youngs_modulus=3.4e9)
        run["fx"] = run["fx"] * 0.0
        write_csv(tmp_path / f"r{k}.csv", run)
        rows.append(f"r{k}.csv,{d}")
    (tmp_path / "truth.csv").write_text("\n".join(rows) + "\n")
    with pytest.warns(UserWarning, match="channel 'fx' holds 0 in every strike"):
        fit = vibrissa.calibrate("e1", tmp_path, finalists=1)
    assert fit["left_out"] == [["fx", 0.0]]
    assert "fx" not in [c["name"] for c in fit["channels"]]
