"""Whisker physics from Python: simulate a whisker struck by moving objects.

>>> import vibrissa
>>> run = vibrissa.simulate("e2", d=0.023, v=0.9)
>>> run["theta12"].shape
(151,)

A scenario is a built-in name (``vibrissa.builtins()``: the seed experiments ``e1`` and ``e2``)
or the path of a TOML scenario file, as for the ``vibrissa`` command line. Keyword arguments
override the scenario's keys: ``d=0.023``, ``whisker__length=0.04`` (``__`` stands for the dot of
``whisker.length``), or ``overrides={"objects.0.friction": 0.3}``. All quantities are SI.
"""

import json
import math
import os
from collections.abc import Mapping
from numbers import Integral, Real

from . import _vibrissa
from ._sweep import SweepError, sweep

__all__ = [
    "simulate",
    "sweep",
    "estimate",
    "estimate_shapes",
    "calibrate",
    "methods",
    "Filter",
    "SweepError",
    "builtins",
    "COLUMNS",
    "CHANNELS",
    "__version__",
]
__version__ = _vibrissa.__version__

#: The columns of a run, in order: time (s), the first two joint angles (rad), the base moment
#: (N·m) and force (N), whether the whisker touches an object (1 or 0), the contact point
#: (m, world frame) and its arc length from the base (m; NaN without contact).
COLUMNS = ("t", "theta01", "theta12", "m0", "fx", "fy", "contact", "cx", "cy", "s")


#: The channels a recording holds and the filter reads, in order: the first two joint angles
#: (rad), the base moment (N·m) and force (N).
CHANNELS = ("theta01", "theta12", "m0", "fx", "fy")


def builtins():
    """The names of the built-in scenarios."""
    return list(_vibrissa.builtins())


def _value(key, value):
    """A scenario value as the text of a ``key=value`` override."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Integral):
        return str(int(value))
    if isinstance(value, Real):
        x = float(value)
        if not math.isfinite(x):
            raise ValueError(f"{key} = {value}: a scenario value must be a finite number")
        return repr(x)
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(f"{key}[{i}]", v) for i, v in enumerate(value)) + "]"
    raise TypeError(
        f"{key}: expected a number, a bool, a string or a list of them, "
        f"not {type(value).__name__}"
    )


def _overrides(overrides, keys):
    """``key=value`` texts from an ``overrides`` mapping and keyword arguments."""
    sets = []
    if overrides is not None:
        if not hasattr(overrides, "items"):
            raise TypeError(
                f"overrides: expected a mapping of scenario keys to values, "
                f"not {type(overrides).__name__}"
            )
        for key, value in overrides.items():
            if not isinstance(key, str):
                raise TypeError(f"overrides: keys are scenario keys (str), not {key!r}")
            sets.append(f"{key}={_value(key, value)}")
    for name, value in keys.items():
        key = name.replace("__", ".")
        sets.append(f"{key}={_value(key, value)}")
    return sets


def _scenario(scenario):
    if isinstance(scenario, os.PathLike):
        return os.fspath(scenario)
    if isinstance(scenario, str):
        return scenario
    raise TypeError(
        "scenario: expected a built-in name such as 'e2' or the path of a TOML scenario file, "
        f"not {type(scenario).__name__}"
    )


def simulate(scenario="e2", *, overrides=None, as_frame=False, **keys):
    """Simulate one run of ``scenario`` and return its columns.

    Parameters
    ----------
    scenario : str, os.PathLike or dict
        A built-in name (``"e1"``, ``"e2"``), the path of a TOML scenario file, or a dict of a
        scenario file's keys (tables as nested dicts, e.g. ``{"experiment": "e2", "d": 0.02,
        "whisker": {"preset": "w30"}}``).
    overrides : mapping, optional
        Scenario keys and values, e.g. ``{"whisker.length": 0.04}``.
    as_frame : bool
        Return a ``pandas.DataFrame`` (pandas must be installed) instead of a dict.
    **keys
        More overrides, ``__`` standing for ``.``: ``d=0.023``, ``whisker__length=0.04``.

    Returns
    -------
    dict of str to numpy.ndarray, or pandas.DataFrame
        The columns of :data:`COLUMNS`, one value per output sample, SI units; for a scenario
        with an array of whiskers (``[[whiskers]]``), ``t`` and each whisker's other columns
        prefixed with its name (``c1.theta01``, ...).

    Raises
    ------
    ValueError
        An unknown scenario or key, a value out of its range, a run that diverges: the message
        names the key and what is allowed, as the command line's does.
    TypeError
        An argument of the wrong type.
    """
    sets = _overrides(overrides, keys)
    name, text = _scenario_args(scenario)
    if text is not None:
        columns = _vibrissa.simulate_json(text, sets)
    else:
        columns = _vibrissa.simulate(name, sets)
    if as_frame:
        try:
            import pandas
        except ImportError as e:
            raise ImportError("as_frame=True needs pandas: pip install pandas") from e
        return pandas.DataFrame(dict(columns))
    return dict(columns)


def _scenario_args(scenario):
    """``(name or path, JSON text of a dict)``: one of them ``None``."""
    if isinstance(scenario, Mapping):
        try:
            return None, json.dumps(scenario, allow_nan=False)
        except ValueError:
            raise ValueError("scenario: a dict's values must be finite numbers") from None
        except TypeError as e:
            raise TypeError(f"scenario: {e}") from None
    return _scenario(scenario), None


def _whisker_specs(whisker_from):
    """``whisker_from`` as ``--whisker-from`` reads it: a list of ``FILE`` and ``NAME=FILE``."""
    if whisker_from is None:
        return None
    if isinstance(whisker_from, dict):
        specs = []
        for name, file in whisker_from.items():
            if name is None:
                specs.insert(0, os.fspath(file))
            elif not isinstance(name, str):
                raise ValueError(
                    f"whisker_from: the keys are whisker names (or None), not {name!r}"
                )
            else:
                specs.append(f"{name}={os.fspath(file)}")
        return specs
    return [os.fspath(whisker_from)]


def _noise_statement(noise):
    """``noise`` as the command line's ``--noise`` text."""
    if noise is None:
        return "auto"
    if isinstance(noise, str):
        return noise
    if hasattr(noise, "items"):
        parts = []
        for key, x in noise.items():
            if key not in CHANNELS:
                raise ValueError(
                    f"noise: unknown channel {key!r}; channels are {', '.join(CHANNELS)}"
                )
            x = _number(f"noise[{key!r}]", x)
            if not (math.isfinite(x) and x >= 0):
                raise ValueError(f"noise[{key!r}] = {x}: a sensor noise is a finite number >= 0")
            parts.append(f"{key}={x!r}")
        return ",".join(parts) if parts else "auto"
    raise TypeError(
        f"noise: expected 'auto', 'none' or a mapping of channels to sigmas, not {type(noise).__name__}"
    )


def _recording(k, obs, whisker=None):
    """One recording for the native layer: a path, or (name, t, channels) arrays; of an array
    of whiskers' recording, the columns of ``whisker``."""
    import numpy

    if isinstance(obs, (str, os.PathLike)):
        return os.fspath(obs)
    if hasattr(obs, "columns") and hasattr(obs, "to_numpy"):  # a pandas DataFrame
        obs = {str(c): obs[c].to_numpy() for c in obs.columns}
    if not hasattr(obs, "items"):
        raise TypeError(
            f"recording {k}: expected a CSV path, a dict of arrays or a pandas.DataFrame, "
            f"not {type(obs).__name__}"
        )
    names = [c[: -len(".theta01")] for c in obs if isinstance(c, str) and c.endswith(".theta01")]
    if whisker is not None:
        if whisker not in names:
            raise ValueError(
                f"recording {k} has no whisker {whisker!r}; its whiskers are "
                f"{', '.join(names) if names else 'none (one whisker, unprefixed columns)'}"
            )
        prefix = whisker + "."
        obs = {"t": obs["t"], **{c[len(prefix):]: v for c, v in obs.items() if c.startswith(prefix)}}
    elif "theta01" not in obs and names:
        raise ValueError(
            f"recording {k} holds the columns of several whiskers ({', '.join(names)}): "
            "choose one with whisker="
        )
    if "t" not in obs:
        raise ValueError(f"recording {k}: no 't' column (sample times, s)")

    def array(name):
        try:
            a = numpy.ascontiguousarray(obs[name], dtype=numpy.float64)
        except (TypeError, ValueError):
            raise TypeError(f"recording {k}: column {name!r} is not an array of numbers") from None
        if a.ndim != 1:
            raise ValueError(f"recording {k}: column {name!r} has {a.ndim} dimensions, expected 1")
        return a

    return (
        f"recording {k}",
        array("t"),
        [array(c) if c in obs else None for c in CHANNELS],
    )


def methods():
    """The estimators' names, as ``vibrissa estimate --list`` gives them."""
    return list(_vibrissa.methods())


def estimate(
    obs,
    scenario="e2",
    method="krr-local",
    *,
    noise="auto",
    seed=1,
    randomise=None,
    particles=None,
    islands=None,
    check=False,
    whisker=None,
    max_delay=0.0,
    pool=None,
    pool_rounds=None,
    pool_search=None,
    pool_gains=True,
    overrides=None,
    verbose=False,
    whisker_from=None,
    **keys,
):
    """Estimate the scenario's unknowns (for ``e2``: the distance ``d`` and speed ``v`` of the
    box) from a recording, as ``vibrissa estimate --json`` does.

    >>> run = vibrissa.simulate("e2", d=0.023, v=0.9)
    >>> est = vibrissa.estimate(run, "e2", method="knn", noise="none")
    >>> est["d"]["mean"], est["d"]["ci90"]

    Parameters
    ----------
    obs : str, os.PathLike, dict of arrays, pandas.DataFrame, or a list of them
        A recording: the path of a contract CSV file, or columns ``t`` and any of
        :data:`CHANNELS` (``theta01`` and ``theta12`` at least) as arrays. Any constant sample
        rate and length. A list estimates each; their sensor noise is pooled where they agree and
        each method is trained once per timing, as for several ``--obs`` files.
    scenario : str, os.PathLike or dict
        The scenario the recordings come from: a built-in name, a scenario file with
        ``[unknowns]`` (e.g. written by ``vibrissa calibrate``) or a dict of its keys.
    method : str
        An estimator of :func:`methods` (``"pf"`` is the particle filter).
    noise : "auto", "none" or mapping
        The sensor noise: estimated from the recordings (``"auto"``), none, or stated per channel
        (standard deviation, SI; channels left out are estimated).
    seed : int
        Seed of the training runs (and of the filter).
    randomise : bool, optional
        The whisker is known only roughly: the discriminative methods train on whiskers drawn
        around the scenario's; the filter (``"pf"``) entertains such whiskers and carries the
        sensors' gains and offsets as unknowns (reported as ``"sensors.<channel>.gain"``...).
        Default (None): on a calibrated scenario (written by ``vibrissa calibrate``), over what
        its calibration leaves uncertain; otherwise not.
    particles : int, optional
        Particles of ``method="pf"`` (default 1000, or 4000 with ``randomise=True``).
    islands : int, optional
        Independent filters the particles of ``method="pf"`` are split among, each with its own
        random streams, merged so that the intervals hold the spread between them (default 3,
        or 1 for a pooled batch, which filters again as three any recording on which its
        favourite whisker lost every particle; each keeps at least 1000 particles: 4000 run as
        three, 1000 as one).
    check : bool
        Add the model check (``"check"``): does the scenario explain the recording at its estimate?
    whisker : str, optional
        For a recording of an array of whiskers (columns ``c1.theta01``, ...), the whisker whose
        columns are read. Required when the scenario itself holds ``[[whiskers]]``: the methods
        then train on that whisker where the array mounts it (``"pf"`` only on one at the
        origin).
    max_delay : float
        The recordings may start up to this many seconds before the approach: the
        discriminative methods read them aligned at the contact's onset, the filter takes the
        start delay ``t0`` as an unknown. With 0 (the default), a batch in which a recording
        leaves rest later than any run of the scenario is read so, with a warning.
    pool : bool, optional
        ``method="pf"`` on a list of recordings made with one whisker known only roughly: the
        filter learns that whisker from all of them together (six rounds, each filtering the
        batch among whiskers drawn around those the whole batch favours), as ``vibrissa
        estimate --pool`` does. Needs the filter's alternative whiskers (``randomise=True``, or a
        scenario the recordings defy). Default (None): pooled when the batch holds 5 recordings
        or more, the filter entertains several whiskers and the scenario is not calibrated;
        ``pool=False`` filters each recording alone (recordings of different whiskers).
    pool_rounds : int, optional
        When pooling: the rounds of pooling after the first filtering of the batch
        (default 6, as ``--pool-rounds``); fewer are faster and learn the whisker less well.
    pool_search : int, optional
        When pooling: the rounds before the last filter at most this many of the recordings,
        spread through the list (default 20, as ``--pool-search``); the last round filters all.
    pool_gains : bool, optional
        When pooling 10 recordings or more: whether the batch also learns the joint angles'
        gains together (the default: they stand for the recording's chain and angle tracker,
        which its strikes share); ``False`` lets each recording learn them alone
        (``--no-pool-gains``).
    verbose : bool
        Print what is trained and every warning (they are also attached as ``"warnings"``).
    whisker_from : str, os.PathLike or dict, optional
        A scenario file of one whisker, typically the one :func:`calibrate` fitted to labelled
        strikes: the scenario is given its whisker, chain, sensors and calibration record (as
        ``--whisker-from``), so that a whisker calibrated on one experiment serves another;
        contact is stepped as finely as in that file (``contact_substeps``). For a scenario
        of an array, a dict gives named whiskers files of their own, as for
        :func:`estimate_shapes`.
    overrides, **keys
        Scenario overrides, as for :func:`simulate` (applied after ``whisker_from``).

    Returns
    -------
    dict, or a list of dicts for a list of recordings
        The contract's estimate object: per unknown ``{"mean", "std", "ci90"}``, ``"method"``,
        ``"seconds"``, ``"noise"`` (per channel read), ``"filter"`` (pf), ``"check"``, and
        ``"warnings"`` (the messages about this recording or the whole batch, empty when all is
        well), plus ``"file"`` for each of a list of recordings.
    """
    several = isinstance(obs, (list, tuple))
    if whisker is not None and not isinstance(whisker, str):
        raise TypeError(f"whisker: expected a name (str), not {type(whisker).__name__}")
    inputs = [_recording(k, o, whisker) for k, o in enumerate(obs if several else [obs])]
    if not inputs:
        raise ValueError("obs: no recordings given")
    if not isinstance(method, str):
        raise TypeError(f"method: expected a name (str), not {type(method).__name__}")
    seed = _count("seed", seed, 0)
    if particles is not None:
        particles = _count("particles", particles, 1)
    if islands is not None:
        islands = _count("islands", islands, 1)
        if islands > 64:
            raise ValueError(f"islands: expected 1 to 64 islands, not {islands}")
    max_delay = _seconds("max_delay", max_delay)
    if pool_rounds is not None:
        pool_rounds = _count("pool_rounds", pool_rounds, 1)
    if pool_search is not None:
        pool_search = _count("pool_search", pool_search, 2)
    name, text = _scenario_args(scenario)
    rows, messages = _vibrissa.estimate(
        name,
        text,
        _overrides(overrides, keys),
        inputs,
        method,
        _noise_statement(noise),
        seed,
        None if randomise is None else bool(randomise),
        particles,
        islands,
        bool(check),
        whisker,
        max_delay,
        None if pool is None else bool(pool),
        pool_rounds,
        pool_search,
        _whisker_specs(whisker_from),
        bool(pool_gains),
    )
    if verbose:
        import sys

        for m in messages:
            print(m, file=sys.stderr)
    warnings = [m[len("warning: "):] for m in messages if m.startswith("warning: ")]
    names = [i if isinstance(i, str) else i[0] for i in inputs]
    out = []
    for name, r in zip(names, rows):
        row = json.loads(r)
        # Each recording's own warnings, and those of the batch as a whole.
        row["warnings"] = [
            w for w in warnings if f"`{name}`" in w or not any(f"`{n}`" in w for n in names)
        ]
        out.append(row)
    return out if several else out[0]


def estimate_shapes(
    obs,
    shapes="e3",
    *,
    whiskers=None,
    training=800,
    noise="auto",
    seed=1,
    randomise=False,
    method="shape-krr",
    verbose=False,
    bank=3200,
    whisker_from=None,
    particles=None,
):
    """Which object struck the whiskers, and where: the class posterior and the most probable
    class's pose, as ``vibrissa estimate --shapes --json`` does.

    >>> run = vibrissa.simulate("runs/run0002-circle.toml")   # written by experiment e3 --export
    >>> est = vibrissa.estimate_shapes(run, "e3")
    >>> est["class"], est["x"]["mean"]

    Parameters
    ----------
    obs : str, os.PathLike, dict of arrays, pandas.DataFrame, or a list of them
        A recording of the family's whiskers: a contract CSV path, or columns ``t`` and each
        whisker's prefixed channels (``c1.theta01``, ...; a family of one whisker: the plain
        channels). A list estimates each, training once; all must share one timing.
    shapes : str or os.PathLike
        The shape family: ``"e3"`` or a file whose ``[classes]`` table names each class's
        scenario file.
    whiskers : list of str, optional
        The whiskers read (default: all of the family's), e.g. ``["c3"]``.
    training : int
        Training runs per class (at least 20).
    noise, seed, randomise, verbose
        As for :func:`estimate`.
    method : str
        ``"shape-krr"`` (reads the recording whole), ``"shape-esn"`` (online: an echo-state
        network that updates the class posterior after every sample), ``"shape-bank"`` (the
        recording's likelihood under 3200 noise-free runs per class: best on noisy recordings,
        several minutes to simulate its bank), ``"shape-pf"`` (a particle filter over each
        class's pose, online) or ``"shape-mix"`` (the bank and the filter pooled).
    bank : int
        With ``"shape-bank"``: noise-free runs per class in its bank (at least ``training``).
    whisker_from : str, os.PathLike or dict, optional
        A scenario file of one whisker, typically the one :func:`calibrate` fitted to labelled
        strikes of your whisker: every whisker of the family is given its whisker, chain and
        sensors (and its calibration record), so that the estimators train on your whisker,
        with contact stepped as finely as in that file (``contact_substeps``). A dict gives
        whiskers of the array their own files, ``{"c2": "c2.toml", "c3": "c3.toml"}`` (each
        calibrated on that whisker's strikes; all fitted on one chain), and its key ``None``
        the file for every whisker it does not name (``--whisker-from NAME=FILE``).
    particles : int, optional
        With ``"shape-pf"`` or ``"shape-mix"``: particles per class of the filter (default
        1000; at least 2); refused with the other methods.

    Returns
    -------
    dict, or a list of dicts for a list of recordings
        ``"class"`` (each class's probability), the most probable class's unknowns as
        ``{"mean", "std", "ci90"}``, ``"method"``, ``"seconds"``, ``"noise"`` and
        ``"warnings"``, plus ``"file"`` for each of a list of recordings. With
        ``"shape-esn"`` or ``"shape-bank"`` also ``"trace"``: each class's probability after
        every sample (a list per class name).
    """
    several = isinstance(obs, (list, tuple))
    shapes = os.fspath(shapes)
    if whiskers is not None:
        if isinstance(whiskers, str) or not all(isinstance(w, str) for w in whiskers):
            raise TypeError("whiskers: expected a list of whisker names")
        whiskers = list(whiskers)
    names = _vibrissa.shape_whiskers(shapes, whiskers)
    recordings = obs if several else [obs]
    if not recordings:
        raise ValueError("obs: no recordings given")
    inputs = []
    for k, o in enumerate(recordings):
        if isinstance(o, (str, os.PathLike)):
            path = os.fspath(o)
            inputs.append([(path, w) for w in names] if names else [(path, None)])
        else:
            inputs.append(
                [(_recording(k, o, w), w) for w in names] if names else [(_recording(k, o), None)]
            )
    training = _count("training", training, 20)
    seed = _count("seed", seed, 0)
    bank = _count("bank", bank, 20)
    if particles is not None:
        particles = _count("particles", particles, 2)
    if not isinstance(method, str):
        raise TypeError("method: expected a method name such as 'shape-esn'")
    rows, messages, traces, classes = _vibrissa.estimate_shapes(
        shapes,
        whiskers,
        inputs,
        _noise_statement(noise),
        seed,
        bool(randomise),
        training,
        method,
        bank,
        _whisker_specs(whisker_from),
        particles,
    )
    if verbose:
        import sys

        for m in messages:
            print(m, file=sys.stderr)
    warnings = [m[len("warning: "):] for m in messages if m.startswith("warning: ")]
    out = []
    for k, r in enumerate(rows):
        row = json.loads(r)
        row["warnings"] = warnings
        if traces:
            row["trace"] = {c: [p[i] for p in traces[k]] for i, c in enumerate(classes)}
        out.append(row)
    return out if several else out[0]


def calibrate(
    scenario,
    labelled,
    out=None,
    *,
    ignore_unlisted=False,
    gain_prior=None,
    max_iterations=None,
    finalists=None,
    verbose=False,
    overrides=None,
    **keys,
):
    """Fit the whisker and sensors of a nominal scenario to labelled recordings, as
    ``vibrissa calibrate`` does.

    >>> fit = vibrissa.calibrate("nominal.toml", "strikes/", out="fitted.toml")
    >>> [(p["key"], p["value"], p["std_error"]) for p in fit["parameters"] if p["determined"]]
    >>> vibrissa.estimate("strike.csv", "fitted.toml", method="krr-local")

    Parameters
    ----------
    scenario : str or os.PathLike
        The nominal scenario: what you believe of your whisker, its sensors and the experiment.
    labelled : str or os.PathLike
        A folder of recordings (CSV) with ``truth.csv``: a ``file`` column, then one column per
        label named by its scenario key (``file,d,v``), SI units.
    out : str or os.PathLike, optional
        Where the fitted scenario (TOML) goes; written only when the fit succeeds.
    ignore_unlisted : bool
        Skip CSV files of the folder that ``truth.csv`` does not name (otherwise an error).
    gain_prior : float, optional
        The sensors' gains' relative prior standard deviation about the nominal's (0.1 = known
        to 10%; 0 = none). Default: the command line's.
    max_iterations : int, optional
        Most Levenberg–Marquardt iterations of one fit. Default: the command line's.
    finalists : int, optional
        Starting points carried on to convergence; the lowest minimum is the fit, and the others
        within twice its cost widen the standard errors. Default: the command line's (4).
    verbose : bool
        Print the fit's stages as they pass.
    overrides, **keys
        Overrides of the nominal scenario, as for :func:`simulate`.

    Returns
    -------
    dict
        The command line's ``--json`` report: ``parameters`` (per parameter ``key``, ``unit``,
        ``nominal``, ``value``, ``std_error``, ``determined``, ``note``), ``channels`` (residual
        RMS before and after, noise), ``recordings``, ``iterations``, ``fits``, ``simulations``,
        ``other_minima`` (how many other minima of the cost the standard errors count),
        ``left_out`` (``[channel, value]`` of each channel that holds one value in every strike,
        left out of the fit with a ``UserWarning``), ``flat_in`` (``[file, channel, value]`` of
        each channel that holds one value in one strike while it varies in others, left out of
        that strike with a ``UserWarning``), ``seconds``; plus ``overrides`` (the ``key=value`` texts that make the nominal the fitted
        scenario) and ``scenario``, the fitted scenario's TOML text.
    """
    if gain_prior is not None:
        gain_prior = _number("gain_prior", gain_prior)
    if max_iterations is not None:
        max_iterations = _count("max_iterations", max_iterations, 1)
    if finalists is not None:
        finalists = _count("finalists", finalists, 1)
    if not isinstance(labelled, (str, os.PathLike)):
        raise TypeError(f"labelled: expected a folder's path, not {type(labelled).__name__}")
    if out is not None and not isinstance(out, (str, os.PathLike)):
        raise TypeError(f"out: expected a file's path, not {type(out).__name__}")
    report, stages = _vibrissa.calibrate(
        _scenario(scenario),
        _overrides(overrides, keys),
        os.fspath(labelled),
        None if out is None else os.fspath(out),
        bool(ignore_unlisted),
        gain_prior,
        max_iterations,
        finalists,
    )
    if verbose:
        import sys

        for s in stages:
            print(s, file=sys.stderr)
    report = json.loads(report)
    for name, value in report["left_out"]:
        import warnings

        warnings.warn(
            f"channel '{name}' holds {value:g} in every strike: a sensor that recorded nothing? "
            "It is left out of the fit (leave the column out of the recordings to say so)",
            UserWarning,
            stacklevel=2,
        )
    for file, name, value in report["flat_in"]:
        import warnings

        warnings.warn(
            f"'{file}': channel '{name}' holds {value:g} from the first sample to the last while "
            "it varies in other strikes: a sensor that recorded nothing in this strike? It is "
            "left out of this strike's fit",
            UserWarning,
            stacklevel=2,
        )
    return report


def _count(name, value, least):
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"{name}: expected an int, not {type(value).__name__}")
    if value < least:
        raise ValueError(f"{name} = {value}: at least {least}")
    return value


def _channels(name, values):
    """Five channel values from a mapping (missing channels NaN) or a sequence of five."""
    out = [math.nan] * 5
    if hasattr(values, "items"):
        for key, x in values.items():
            if key not in CHANNELS:
                raise ValueError(f"{name}: unknown channel {key!r}; channels are {', '.join(CHANNELS)}")
            out[CHANNELS.index(key)] = _number(f"{name}[{key!r}]", x)
        return out
    try:
        seq = list(values)
    except TypeError:
        raise TypeError(
            f"{name}: expected a mapping of channels to values or a sequence of five, "
            f"not {type(values).__name__}"
        ) from None
    if len(seq) != 5:
        raise ValueError(f"{name}: expected five values ({', '.join(CHANNELS)}), got {len(seq)}")
    return [_number(f"{name}[{k}]", x) for k, x in enumerate(seq)]


def _number(name, x):
    if isinstance(x, bool) or not isinstance(x, Real):
        raise TypeError(f"{name}: expected a number, not {type(x).__name__}")
    return float(x)


def _seconds(name, x):
    """A duration in [0, 1] s."""
    x = _number(name, x)
    if not (0.0 <= x <= 1.0):
        raise ValueError(f"{name} = {x}: expected seconds between 0 and 1")
    return x


class Filter:
    """The particle filter, fed one sample at a time: a posterior over the scenario's unknowns
    (for ``e2``: the object's distance ``d`` and speed ``v``) after every sample.

    >>> run = vibrissa.simulate("e2", d=0.023, v=0.9)
    >>> f = vibrissa.Filter("e2", particles=1000, noise={"theta01": 1e-3, "theta12": 1e-3,
    ...                     "m0": 1e-8, "fx": 1e-5, "fy": 1e-5})
    >>> for k, t in enumerate(run["t"]):
    ...     post = f.update(t, {c: run[c][k] for c in vibrissa.CHANNELS})
    >>> post["d"]["mean"], post["d"]["ci90"]

    Parameters
    ----------
    scenario : str, os.PathLike or dict
        A built-in name (``"e1"``, ``"e2"``), the path of a scenario file with ``[unknowns]``, or
        a dict of its keys.
    particles : int, optional
        Particles (default 1000, with or without ``randomise``: the filter then keeps up with
        the samples on two cores; 4000 on a calibrated file, randomised there by default, whose
        intervals held about 80% at 1000). :func:`estimate` filters a whole recording of a whisker
        known only roughly with 4000, which read single strikes about a sixth more accurately.
    islands : int, optional
        Independent filters the particles are split among, each with its own random streams,
        fed every sample side by side and merged, so that the intervals hold the spread between
        them (default 3; each keeps at least 1000 particles, so 1000 particles are one filter and
        a calibrated file's 4000 three).
    noise : mapping, optional
        Each channel's sensor noise (standard deviation, SI). Channels left out must be stated by
        the scenario's ``[sensor_noise]``.
    seed : int
        Seed of the filter's random streams (the same seed gives the same bits).
    rate : float, optional
        Sample rate of the recording, Hz (default: the scenario's).
    randomise : bool, optional
        The whisker is known only roughly: the filter entertains 64 whiskers drawn around the
        scenario's and carries the sensors' gains and offsets as unknowns; each posterior then
        also holds ``"sensors.<channel>.gain"`` and ``"sensors.<channel>.offset"``. At the default
        1000 particles it keeps up with the samples on two cores. As on the command line,
        the filter is first run on 24 held-out runs of whiskers drawn alike (about 2 s at 1000
        particles) and every posterior's intervals are widened to hold 90% of their errors
        (the means are unchanged). Default (None): on a calibrated scenario (written by
        ``vibrissa calibrate``), over what its calibration leaves uncertain, as
        :func:`estimate` does; otherwise not, and a scenario file of your own is then taken as
        the exact whisker, with a ``UserWarning``: a real whisker rarely matches its nominal
        file, and the intervals then do not hold.
    overrides, **keys
        Scenario overrides, as for :func:`simulate`.
    """

    def __init__(
        self,
        scenario="e2",
        *,
        particles=None,
        noise=None,
        seed=1,
        rate=None,
        randomise=None,
        islands=None,
        overrides=None,
        **keys,
    ):
        if particles is not None:
            particles = _count("particles", particles, 1)
        if islands is not None:
            islands = _count("islands", islands, 1)
            if islands > 64:
                raise ValueError(f"islands: expected 1 to 64 islands, not {islands}")
        seed = _count("seed", seed, 0)
        if rate is not None:
            rate = _number("rate", rate)
        values = _channels("noise", noise if noise is not None else {})
        name, text = _scenario_args(scenario)
        self._inner = _vibrissa.Filter(
            name,
            text,
            _overrides(overrides, keys),
            values,
            particles,
            seed,
            rate,
            None if randomise is None else bool(randomise),
            islands,
        )

    def update(self, t, sample):
        """Take the sample at time ``t`` (s): a mapping of channels to values (channels left out
        count as missing) or a sequence of the five :data:`CHANNELS`. Returns the posterior
        there: ``{"t", "ess", NAME: {"mean", "std", "ci90"}}`` per unknown. Times must advance
        by whole sample periods (a gap is predicted across)."""
        return self._inner.update(_number("t", t), _channels("sample", sample))

    @property
    def posterior(self):
        """The posterior after the last sample (``None`` before the first)."""
        return self._inner.posterior

    @property
    def trace(self):
        """Every posterior so far as arrays: ``t``, ``ess``, and ``NAME_mean``, ``NAME_std``,
        ``NAME_lo``, ``NAME_hi`` (90% interval) per unknown."""
        return self._inner.trace

    @property
    def unknowns(self):
        """The unknowns the posterior is over, in order."""
        return list(self._inner.unknowns)

    @property
    def particles(self):
        """The number of particles."""
        return self._inner.particles

    @property
    def period(self):
        """The sample period, s."""
        return self._inner.period

    @property
    def noise(self):
        """The sensor noise per channel the filter assumes, SI."""
        return self._inner.noise

    @property
    def counts(self):
        """Particle steps, diverged steps (0 expected), moves undone and resamplings so far, and
        the number of islands."""
        return self._inner.counts
