"""vibrissa.estimate against the command line's `estimate --json`, and its errors."""

import json
import subprocess

import numpy as np
import pytest

import vibrissa
from test_filter import write_csv
from test_simulate import cli

# Sensor noise added to the simulated runs (1/3 of the e2 noisy variant's levels).
SIGMA = {"theta01": 2e-3, "theta12": 5e-3, "m0": 8e-7, "fx": 5e-5, "fy": 4e-5}


def noisy_run(d, v, seed):
    rng = np.random.default_rng(seed)
    run = vibrissa.simulate("e2", d=d, v=v)
    for c, s in SIGMA.items():
        run[c] = run[c] + rng.normal(0.0, s, len(run[c]))
    return run


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("recordings")
    paths = []
    for k, (d, v) in enumerate([(0.021, 0.7), (0.027, 1.1)]):
        path = folder / f"r{k}.csv"
        write_csv(path, noisy_run(d, v, k))
        paths.append(path)
    return paths


def cli_estimates(paths, *args):
    out = subprocess.run(
        [cli(), "estimate", "--experiment", "e2", "--json", *args, "--obs", *paths],
        check=True, capture_output=True, text=True,
    )
    return [json.loads(line) for line in out.stdout.splitlines() if line.strip()] if len(
        paths) > 1 else [json.loads(out.stdout)]


def same(mine, theirs):
    """Equal to the last digit, apart from the time taken and the warnings."""
    a = {k: v for k, v in mine.items() if k not in ("seconds", "warnings")}
    b = {k: v for k, v in theirs.items() if k != "seconds"}
    # JSON arrays and tuples alike.
    return json.loads(json.dumps(a)) == b


def test_a_discriminative_method_gives_the_command_line_s_estimate(recordings):
    mine = vibrissa.estimate(recordings[0], "e2", method="krr-local")
    (theirs,) = cli_estimates(recordings[:1], "--method", "krr-local")
    assert same(mine, theirs), (mine, theirs)
    assert abs(mine["d"]["mean"] - 0.021) < 5e-4
    assert set(mine["noise"]) == set(vibrissa.CHANNELS)
    assert mine["warnings"] == []


def test_the_filter_on_a_batch_gives_the_command_line_s_estimates(recordings):
    mine = vibrissa.estimate(recordings, "e2", method="pf", particles=200, seed=3, check=True)
    theirs = cli_estimates(recordings, "--method", "pf", "--particles", "200", "--seed", "3",
                           "--check")
    assert len(mine) == 2
    for m, t in zip(mine, theirs):
        assert same(m, t), (m, t)
        # The check ran on both (its verdict on a 200-particle estimate is the filter's scatter,
        # not this binding's: at d = 21 mm, v = 0.7 m/s the speed may come out 0.02 m/s off).
        assert m["filter"]["diverged_steps"] == 0 and isinstance(m["check"]["explained"], bool)
    assert mine[1]["file"] == str(recordings[1])


def test_the_filter_split_into_islands_gives_the_command_line_s_estimate(recordings):
    mine = vibrissa.estimate(recordings[0], "e2", method="pf", particles=2000, islands=2)
    (theirs,) = cli_estimates(recordings[:1], "--method", "pf", "--particles", "2000",
                              "--islands", "2")
    assert same(mine, theirs), (mine, theirs)
    assert mine["filter"]["islands"] == 2 and mine["filter"]["particles"] == 2000
    whole = vibrissa.estimate(recordings[0], "e2", method="pf", particles=2000, islands=1)
    assert whole["filter"]["islands"] == 1 and whole["d"] != mine["d"]
    with pytest.raises(ValueError, match="islands"):
        vibrissa.estimate(recordings[0], "e2", method="pf", islands=0)
    with pytest.raises(ValueError, match="islands"):
        vibrissa.estimate(recordings[0], "e2", method="pf", islands=65)


def test_the_filter_on_a_whisker_known_roughly(recordings):
    mine = vibrissa.estimate(recordings[0], "e2", method="pf", particles=300, randomise=True)
    (theirs,) = cli_estimates(recordings[:1], "--method", "pf", "--particles", "300",
                              "--randomise")
    assert same(mine, theirs), (mine, theirs)
    # The sensors' gains and offsets are unknowns of the filter, reported by scenario key.
    for c in vibrissa.CHANNELS:
        assert f"sensors.{c}.gain" in mine and f"sensors.{c}.offset" in mine
    assert abs(mine["d"]["mean"] - 0.021) < 2.5e-3


def test_pooling_a_batch_gives_the_command_line_s_estimates(recordings):
    args = dict(method="pf", particles=320, randomise=True, pool=True, pool_rounds=2)
    mine = vibrissa.estimate(recordings, "e2", **args)
    theirs = cli_estimates(recordings, "--method", "pf", "--particles", "320", "--randomise",
                           "--pool", "--pool-rounds", "2")
    for m, t in zip(mine, theirs):
        assert same(m, t), (m, t)
        assert "whisker.youngs_modulus" in m
    with pytest.raises(ValueError, match="at least 2"):
        vibrissa.estimate(recordings[:1], "e2", **args)
    with pytest.raises(ValueError, match="method=.pf"):
        vibrissa.estimate(recordings, "e2", method="knn", pool=True)
    with pytest.raises(ValueError, match="randomise=True"):
        vibrissa.estimate(recordings, "e2", method="pf", particles=50, randomise=False, pool=True)
    with pytest.raises(ValueError, match="pool_rounds = 0: at least 1"):
        vibrissa.estimate(recordings, "e2", **dict(args, pool_rounds=0))
    with pytest.raises(ValueError, match="with pool=True"):
        vibrissa.estimate(recordings, "e2", **dict(args, pool=False))
    with pytest.raises(ValueError, match="pool_search.*at least 2"):
        vibrissa.estimate(recordings, "e2", **dict(args, pool_search=1))
    # The joint angles' gains learnt recording by recording, as --no-pool-gains.
    apart = vibrissa.estimate(recordings, "e2", **dict(args, pool_gains=False))
    theirs = cli_estimates(recordings, "--method", "pf", "--particles", "320", "--randomise",
                           "--pool", "--pool-rounds", "2", "--no-pool-gains")
    for m, t in zip(apart, theirs):
        assert same(m, t), (m, t)
    with pytest.raises(ValueError, match="pool_gains=False.*with pool=True"):
        vibrissa.estimate(recordings, "e2", **dict(args, pool=False, pool_gains=False))


def test_a_batch_of_five_is_pooled_unless_told_not_to(recordings, tmp_path):
    batch = list(recordings)
    for k, (d, v) in enumerate([(0.017, 0.5), (0.024, 1.3), (0.019, 0.9)]):
        path = tmp_path / f"more{k}.csv"
        write_csv(path, noisy_run(d, v, 10 + k))
        batch.append(path)
    args = dict(method="pf", particles=320, randomise=True, pool_rounds=1)
    mine = vibrissa.estimate(batch, "e2", **args)
    theirs = cli_estimates(batch, "--method", "pf", "--particles", "320", "--randomise",
                           "--pool-rounds", "1")
    pooled = cli_estimates(batch, "--method", "pf", "--particles", "320", "--randomise",
                           "--pool", "--pool-rounds", "1")
    assert len(mine) == 5
    for m, t, p in zip(mine, theirs, pooled):
        assert same(m, t) and same(m, p), (m, t, p)
    # A search on 3 of the 5, as the command line's --pool-search.
    searched = vibrissa.estimate(batch, "e2", **dict(args, pool_search=3))
    theirs = cli_estimates(batch, "--method", "pf", "--particles", "320", "--randomise",
                           "--pool-rounds", "1", "--pool-search", "3")
    assert len(searched) == 5
    for m, t in zip(searched, theirs):
        assert same(m, t), (m, t)
    alone = vibrissa.estimate(batch, "e2", method="pf", particles=320, randomise=True,
                              pool=False)
    theirs = cli_estimates(batch, "--method", "pf", "--particles", "320", "--randomise",
                           "--no-pool")
    for m, t in zip(alone, theirs):
        assert same(m, t), (m, t)
    assert any(a["d"] != m["d"] for a, m in zip(alone, mine))


def test_arrays_a_frame_and_a_path_give_the_same_estimate(recordings):
    run = noisy_run(0.021, 0.7, 0)
    from_path = vibrissa.estimate(recordings[0], method="knn")
    from_dict = vibrissa.estimate({c: run[c] for c in ("t",) + vibrissa.CHANNELS}, method="knn")
    for name in ("d", "v"):
        assert from_dict[name] == from_path[name]
    pandas = pytest.importorskip("pandas")
    frame = pandas.DataFrame(run)
    from_frame = vibrissa.estimate(frame, method="knn")
    assert from_frame["d"] == from_path["d"]


def test_stated_noise_and_a_scenario_dict(recordings):
    mine = vibrissa.estimate(recordings[0], {"experiment": "e2"}, method="template",
                             noise={"theta12": 5e-3})
    (theirs,) = cli_estimates(recordings[:1], "--method", "template", "--noise", "theta12=0.005")
    assert same(mine, theirs), (mine, theirs)
    assert mine["noise"] == {"theta12": 5e-3}


def test_the_whisker_of_another_file_as_on_the_command_line(recordings, tmp_path):
    own = tmp_path / "own.toml"
    own.write_text('experiment = "e2"\n[whisker]\npreset = "w30"\nyoungs_modulus = 3.6e9\n'
                   '[sensors]\ntheta12 = { gain = 0.9 }\n')
    mine = vibrissa.estimate(recordings[0], "e2", method="knn", whisker_from=own,
                             randomise=False)
    (theirs,) = cli_estimates(recordings[:1], "--method", "knn", "--whisker-from", str(own),
                              "--no-randomise")
    assert same(mine, theirs), (mine, theirs)
    (nominal,) = cli_estimates(recordings[:1], "--method", "knn", "--no-randomise")
    assert mine["d"] != nominal["d"]
    with pytest.raises(ValueError, match="whisker_from"):
        vibrissa.estimate(recordings[0], "e2", method="knn", whisker_from=tmp_path / "no.toml")


def test_a_recording_at_another_rate(recordings):
    # 2 kHz: the method trains on 2 kHz runs of the scenario.
    run = vibrissa.simulate("e2", d=0.024, v=0.9, sample_rate=2000.0)
    est = vibrissa.estimate(run, method="krr-local", noise="none")
    assert abs(est["d"]["mean"] - 0.024) < 5e-4


def test_a_recording_that_starts_before_the_approach(recordings):
    # 30 ms of rest (noise only) before the strike: seen, said, and read at the contact, as on the
    # command line.
    run = noisy_run(0.021, 0.7, 5)
    rng = np.random.default_rng(9)
    late = {"t": np.arange(len(run["t"]) + 30) * 1e-3}
    for c, s in SIGMA.items():
        late[c] = np.concatenate([rng.normal(0.0, s, 30), run[c]])
    est = vibrissa.estimate(late, method="knn")
    assert any("seems to start before the approach" in w for w in est["warnings"]), est
    assert abs(est["d"]["mean"] - 0.021) < 1.5e-3 and abs(est["v"]["mean"] - 0.7) < 0.2, est
    stated = vibrissa.estimate(late, method="knn", max_delay=0.04)
    assert not any("seems to start" in w for w in stated["warnings"]), stated
    with pytest.raises(ValueError, match="max_delay"):
        vibrissa.estimate(late, method="knn", max_delay=-1.0)
    with pytest.raises(ValueError, match="max_delay"):
        vibrissa.estimate(late, method="knn", max_delay=0.2)


def test_a_scenario_the_recording_defies_is_randomised_unless_told_not_to():
    # Another chain and material than the scenario's: the method estimates again on whiskers
    # drawn around the scenario's, and says so.
    rng = np.random.default_rng(3)
    run = vibrissa.simulate("e2", d=0.021, v=0.7, segments=50, discretisation="seed",
                            overrides={"whisker.youngs_modulus": 3.6e9})
    for c, s in SIGMA.items():
        run[c] = run[c] + rng.normal(0.0, 3 * s, len(run[c]))
    said = "estimating again on whiskers drawn around it"
    est = vibrissa.estimate(run, method="knn")
    assert any(said in w for w in est["warnings"]), est["warnings"]
    kept = vibrissa.estimate(run, method="knn", randomise=False)
    assert not any(said in w for w in kept["warnings"]), kept["warnings"]
    assert est["d"]["std"] > kept["d"]["std"]


def test_bad_input_raises_naming_what_is_wrong(recordings, tmp_path):
    run = noisy_run(0.021, 0.7, 0)
    with pytest.raises(ValueError, match="unknown method `nope`"):
        vibrissa.estimate(recordings[0], method="nope")
    bad = dict(run)
    bad["theta12"] = bad["theta12"].copy()
    bad["theta12"][5] = np.inf
    with pytest.raises(ValueError, match="theta12 has an infinite value in data row 6"):
        vibrissa.estimate(bad, method="knn")
    # Missing values (NaN) beyond a tenth of a channel are more than a discriminative method
    # fills in.
    bad["theta12"][5:40] = np.nan
    with pytest.raises(ValueError, match="theta12 misses 35 of its 151 values"):
        vibrissa.estimate(bad, method="knn")
    gap = dict(run)
    gap["t"] = gap["t"].copy()
    gap["t"][50:] += 0.01
    with pytest.raises(ValueError, match="sample step before data row 51"):
        vibrissa.estimate(gap, method="knn")
    # Read from a file, a bad row is named by the file's line (its header is line 1).
    path = tmp_path / "nan.csv"
    cols = ["t", "theta01", "theta12", "m0", "fx", "fy"]
    with open(path, "w") as f:
        f.write(",".join(cols) + "\n")
        for k in range(len(run["t"])):
            row = [run[c][k] for c in cols]
            f.write(",".join("inf" if (c == "theta12" and k == 5) else repr(float(v))
                             for c, v in zip(cols, row)) + "\n")
    with pytest.raises(ValueError, match="line 7: column `theta12`: `inf` is not finite"):
        vibrissa.estimate(str(path), method="knn")
    with pytest.raises(ValueError, match="no 't' column"):
        vibrissa.estimate({"theta12": run["theta12"]}, method="knn")
    with pytest.raises(TypeError, match="expected a CSV path, a dict of arrays"):
        vibrissa.estimate(42, method="knn")
    with pytest.raises(TypeError, match="column 'theta01' is not an array of numbers"):
        vibrissa.estimate({"t": run["t"], "theta01": ["a"] * 151, "theta12": run["theta12"]})
    with pytest.raises(ValueError, match="noise: unknown channel 'x'"):
        vibrissa.estimate(recordings[0], noise={"x": 1.0})
    with pytest.raises(ValueError, match="No such file"):
        vibrissa.estimate("/nonexistent/recording.csv")
    with pytest.raises(ValueError, match="particles = 0"):
        vibrissa.estimate(recordings[0], method="pf", particles=0)
    with pytest.raises(ValueError, match="no recordings"):
        vibrissa.estimate([])
    # A time column in milliseconds: 1 Hz, fewer than 10 samples in the scenario's 0.15 s run.
    ms = dict(run)
    ms["t"] = ms["t"] * 1000.0
    with pytest.raises(ValueError, match="`t` must be in seconds"):
        vibrissa.estimate(ms, method="knn")
    with pytest.raises(ValueError, match="`t` must be in seconds"):
        vibrissa.estimate(ms, method="pf", randomise=True)


def test_angles_in_degrees_are_warned_of():
    run = noisy_run(0.021, 0.7, 0)
    deg = dict(run)
    deg["theta01"] = np.degrees(run["theta01"])
    deg["theta12"] = np.degrees(run["theta12"])
    est = vibrissa.estimate(deg, method="knn", randomise=False)
    said = " ".join(est["warnings"])
    assert "channel theta01 spans up to" in said and "degrees" in said, est["warnings"]
    assert "channel theta12" in said
    est = vibrissa.estimate(run, method="knn", randomise=False)
    assert not any("spans up to" in w for w in est["warnings"]), est["warnings"]


def test_one_whisker_of_an_array_recording(tmp_path):
    from test_simulate import ROOT

    example = str(ROOT / "examples" / "scenarios" / "array_row.toml")
    run = vibrissa.simulate(example)
    path = tmp_path / "row.csv"
    subprocess.run([cli(), "simulate", example, "--out", path], check=True, capture_output=True)
    from_path = vibrissa.estimate(path, "e2", method="knn", noise="none", whisker="c1")
    from_arrays = vibrissa.estimate(run, "e2", method="knn", noise="none", whisker="c1")
    assert from_path["d"] == from_arrays["d"]
    assert abs(from_path["d"]["mean"] - 0.015) < 1e-3
    with pytest.raises(ValueError, match=r"several whiskers \(c1, c2, c3\)"):
        vibrissa.estimate(run, "e2", method="knn")
    with pytest.raises(ValueError, match="several whiskers"):
        vibrissa.estimate(path, "e2", method="knn")
    with pytest.raises(ValueError, match="no whisker 'c9'"):
        vibrissa.estimate(run, "e2", method="knn", whisker="c9")


def test_a_recording_of_another_chain_trains_on_that_chain(tmp_path):
    path = tmp_path / "r40.csv"
    subprocess.run([cli(), "simulate", "e2", "--set", "d=0.022", "--set", "v=0.8", "--set",
                    "segments=40", "--out", path], check=True, capture_output=True)
    mine = vibrissa.estimate(path, "e2", method="knn", noise="none")
    (theirs,) = cli_estimates([path], "--method", "knn", "--noise", "none")
    assert same(mine, theirs), (mine, theirs)
    assert abs(mine["d"]["mean"] - 0.022) < 1e-3


def test_missing_values_are_filled_in_for_a_discriminative_method(recordings):
    # A tracker that lost the whisker for a few frames: the discriminative method reads the
    # series with those values interpolated, and says so; the filter skips them.
    run = noisy_run(0.021, 0.7, 0)
    full = vibrissa.estimate(run, method="knn")
    gaps = dict(run)
    for c in ("theta01", "theta12"):
        gaps[c] = gaps[c].copy()
        gaps[c][60:63] = np.nan
    est = vibrissa.estimate(gaps, method="knn")
    said = [w for w in est["warnings"] if "missing values filled in" in w]
    assert len(said) == 1 and "theta01 3 (the longest gap 3 samples, 3 ms)" in said[0], said
    # Three of 151 samples moved by interpolation: the estimate stays within its interval.
    assert abs(est["d"]["mean"] - full["d"]["mean"]) < full["d"]["std"], (est["d"], full["d"])
    assert not any("missing values" in w for w in full["warnings"])


def test_angles_recorded_clockwise_are_warned_of():
    # The angle columns negated (a rig that measures clockwise): the method reads some other
    # strike, and says which channels, negated back, the scenario follows far better.
    run = noisy_run(0.024, 0.9, 3)
    flipped = dict(run)
    for c in ("theta01", "theta12"):
        flipped[c] = -run[c]
    est = vibrissa.estimate(flipped, method="template-interp")
    assert any("with theta01 and theta12 negated" in w for w in est["warnings"]), est["warnings"]
    kept = vibrissa.estimate(run, method="template-interp")
    assert not any("negated" in w for w in kept["warnings"]), kept["warnings"]


def test_a_sensor_that_recorded_nothing_is_left_out_by_the_filter_and_refused_by_a_method():
    # m0 flat at a huge value beside channels that vary: the filter reads the other four, as
    # on the command line; a method that reads m0 raises before it trains.
    run = dict(noisy_run(0.021, 0.7, 6))
    run["m0"] = np.full(len(run["t"]), 1e30)
    est = vibrissa.estimate(run, method="pf", particles=300)
    assert any("`m0`" in w and "left out" in w for w in est["warnings"]), est
    assert "m0" not in est["noise"] and "fx" in est["noise"], est
    assert np.isfinite(est["d"]["mean"]), est
    with pytest.raises(ValueError, match="`m0` holds"):
        vibrissa.estimate(run, method="template-interp")
