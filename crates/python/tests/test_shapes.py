"""vibrissa.estimate_shapes: a class posterior and a pose from recordings of several whiskers."""

import pytest

import vibrissa

# Two whiskers, 10° apart, struck by a peg or a square moving along +y.
COMMON = """duration = 0.08
sample_rate = 1000

[whisker]
preset = "w30"

[[whiskers]]
name = "a"
position = [0.0, 0.0]

[[whiskers]]
name = "b"
position = [-0.0001, 0.001]
angle = 0.17

[[objects]]
{shape}
position = [0.022, -0.012]
velocity = [0.0, 0.8]

[unknowns]
"objects.0.position.0" = {{ range = [0.018, 0.026], name = "x" }}
"""


@pytest.fixture(scope="module")
def family(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shapes")
    (folder / "peg.toml").write_text(COMMON.format(shape='shape = "circle"\nradius = 0.004'))
    (folder / "square.toml").write_text(COMMON.format(shape='shape = "square"\nside = 0.008'))
    path = folder / "shapes.toml"
    path.write_text('[classes]\npeg = "peg.toml"\nsquare = "square.toml"\n')
    return folder, path


def test_a_run_of_each_whisker_gives_a_class_posterior_and_a_pose(family):
    folder, path = family
    run = vibrissa.simulate(folder / "peg.toml")
    assert "a.theta01" in run and "b.theta12" in run
    est = vibrissa.estimate_shapes(run, path, training=30, noise="none")
    assert set(est["class"]) == {"peg", "square"}
    assert abs(sum(est["class"].values()) - 1.0) < 1e-9
    assert est["method"] == "shape-krr"
    best = max(est["class"], key=est["class"].get)
    if best == "peg":
        lo, hi = est["x"]["ci90"]
        assert lo < est["x"]["mean"] < hi
    # One whisker only, and a list of recordings (one object each).
    both = vibrissa.estimate_shapes([run, run], path, whiskers=["a"], training=30, noise="none")
    assert len(both) == 2 and both[0]["class"] == both[1]["class"]


def test_bad_arguments_are_refused_by_name(family):
    folder, path = family
    run = vibrissa.simulate(folder / "peg.toml")
    with pytest.raises(ValueError, match="c9"):
        vibrissa.estimate_shapes(run, path, whiskers=["c9"])
    with pytest.raises(ValueError, match="training"):
        vibrissa.estimate_shapes(run, path, training=5)
    with pytest.raises(TypeError, match="whiskers"):
        vibrissa.estimate_shapes(run, path, whiskers="a")
    with pytest.raises(ValueError):
        vibrissa.estimate_shapes(run, folder / "missing.toml")
    # A sensor that recorded nothing beside channels that vary, named by its column.
    flat = dict(run)
    flat["a.m0"] = [1e30] * len(run["t"])
    with pytest.raises(ValueError, match="`a.m0` holds"):
        vibrissa.estimate_shapes(flat, path, training=30)


def test_the_filter_over_each_class_takes_a_particle_count(family):
    folder, path = family
    run = vibrissa.simulate(folder / "peg.toml")
    est = vibrissa.estimate_shapes(
        run, path, training=30, noise="none", method="shape-pf", particles=50, verbose=True
    )
    assert est["method"] == "shape-pf"
    assert abs(sum(est["class"].values()) - 1.0) < 1e-9
    # Only the filters have particles, and a filter needs two at least.
    with pytest.raises(ValueError, match="particles"):
        vibrissa.estimate_shapes(run, path, training=30, particles=50)
    with pytest.raises(ValueError, match="particles = 1"):
        vibrissa.estimate_shapes(run, path, training=30, method="shape-pf", particles=1)


def test_the_online_estimator_gives_the_posterior_after_every_sample(family):
    folder, path = family
    run = vibrissa.simulate(folder / "peg.toml")
    est = vibrissa.estimate_shapes(run, path, training=30, noise="none", method="shape-esn")
    assert est["method"] == "shape-esn"
    trace = est["trace"]
    assert set(trace) == {"peg", "square"}
    assert len(trace["peg"]) == len(run["t"])
    # The last row of the trace is the estimate.
    for c, p in est["class"].items():
        assert abs(trace[c][-1] - p) < 1e-9
    assert "trace" not in vibrissa.estimate_shapes(run, path, training=30, noise="none")
    with pytest.raises(ValueError, match="shape-esn"):
        vibrissa.estimate_shapes(run, path, training=30, method="knn")


def test_the_bank_weighs_the_recording_against_noise_free_runs(family):
    folder, path = family
    run = vibrissa.simulate(folder / "square.toml")
    est = vibrissa.estimate_shapes(
        run, path, training=30, bank=120, noise="none", method="shape-bank"
    )
    assert est["method"] == "shape-bank"
    assert abs(sum(est["class"].values()) - 1.0) < 1e-9
    # Online too: a posterior after every sample, each row summing to one.
    trace = est["trace"]
    assert set(trace) == set(est["class"])
    assert len(trace["square"]) == len(run["t"])
    for k in range(len(run["t"])):
        assert abs(sum(p[k] for p in trace.values()) - 1.0) < 1e-9
    # The square's pose lies inside its range; a bank smaller than the training runs is
    # raised to them, and a tiny one refused.
    assert 0.015 < est["x"]["mean"] < 0.029
    with pytest.raises(ValueError, match="bank"):
        vibrissa.estimate_shapes(run, path, training=30, bank=3, method="shape-bank")


def test_a_whisker_of_your_own_is_given_to_every_whisker_of_the_family(family, tmp_path):
    folder, path = family
    # The same family written with a stiffer whisker in a compliant follicle ...
    stiff = '[whisker]\npreset = "w30"\nyoungs_modulus = 4.5e9\n' \
        'follicle = { kind = "spring", stiffness = 3e-4, damping = 1e-8 }\n'
    own = tmp_path / "own"
    own.mkdir()
    for name, shape in [("peg", 'shape = "circle"\nradius = 0.004'),
                        ("square", 'shape = "square"\nside = 0.008')]:
        text = COMMON.format(shape=shape).replace('[whisker]\npreset = "w30"\n', stiff)
        (own / f"{name}.toml").write_text(text)
    (own / "shapes.toml").write_text('[classes]\npeg = "peg.toml"\nsquare = "square.toml"\n')
    # ... and that whisker alone, as calibration writes one.
    whisker = tmp_path / "fitted.toml"
    whisker.write_text('experiment = "e2"\n' + stiff)
    run = vibrissa.simulate(own / "square.toml")
    told = vibrissa.estimate_shapes(run, path, training=30, noise="none", whisker_from=whisker)
    written = vibrissa.estimate_shapes(run, own / "shapes.toml", training=30, noise="none")
    nominal = vibrissa.estimate_shapes(run, path, training=30, noise="none")
    assert told["class"] == written["class"]
    assert told["x"] == written["x"]
    assert told["class"] != nominal["class"]
    with pytest.raises(ValueError, match="whisker_from"):
        vibrissa.estimate_shapes(run, path, training=30, whisker_from=folder / "peg.toml")
    # One whisker of the array given its own (a dict by name): as the family written with that
    # whisker for `b` alone; a name the array lacks is refused, listing those it has.
    own_b = tmp_path / "own_b"
    own_b.mkdir()
    for name, shape in [("peg", 'shape = "circle"\nradius = 0.004'),
                        ("square", 'shape = "square"\nside = 0.008')]:
        text = COMMON.format(shape=shape).replace(
            "angle = 0.17\n",
            'angle = 0.17\nwhisker = { youngs_modulus = 4.5e9, follicle = '
            '{ kind = "spring", stiffness = 3e-4, damping = 1e-8 } }\n')
        (own_b / f"{name}.toml").write_text(text)
    (own_b / "shapes.toml").write_text('[classes]\npeg = "peg.toml"\nsquare = "square.toml"\n')
    run_b = vibrissa.simulate(own_b / "square.toml")
    told_b = vibrissa.estimate_shapes(run_b, path, training=30, noise="none",
                                      whisker_from={"b": whisker})
    written_b = vibrissa.estimate_shapes(run_b, own_b / "shapes.toml", training=30, noise="none")
    assert told_b["class"] == written_b["class"]
    assert told_b["x"] == written_b["x"]
    with pytest.raises(ValueError, match="no whisker `z`.*a, b"):
        vibrissa.estimate_shapes(run, path, training=30, whisker_from={"z": whisker})
