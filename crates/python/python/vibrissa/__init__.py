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
from numbers import Real

from . import _vibrissa

__all__ = ["simulate", "Filter", "builtins", "COLUMNS", "CHANNELS", "__version__"]
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
        The columns of :data:`COLUMNS`, one value per output sample, SI units.

    Raises
    ------
    ValueError
        An unknown scenario or key, a value out of its range, a run that diverges: the message
        names the key and what is allowed, as the command line's does.
    TypeError
        An argument of the wrong type.
    """
    sets = _overrides(overrides, keys)
    if isinstance(scenario, Mapping):
        try:
            text = json.dumps(scenario, allow_nan=False)
        except ValueError:
            raise ValueError("scenario: a dict's values must be finite numbers") from None
        except TypeError as e:
            raise TypeError(f"scenario: {e}") from None
        columns = _vibrissa.simulate_json(text, sets)
    else:
        columns = _vibrissa.simulate(_scenario(scenario), sets)
    if as_frame:
        try:
            import pandas
        except ImportError as e:
            raise ImportError("as_frame=True needs pandas: pip install pandas") from e
        return pandas.DataFrame({name: columns[name] for name in COLUMNS})
    return {name: columns[name] for name in COLUMNS}


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
    scenario : str or os.PathLike
        A built-in name (``"e1"``, ``"e2"``) or the path of a scenario file with ``[unknowns]``.
    particles : int
        Particles (1000 runs in real time on two cores).
    noise : mapping, optional
        Each channel's sensor noise (standard deviation, SI). Channels left out must be stated by
        the scenario's ``[sensor_noise]``.
    seed : int
        Seed of the filter's random streams (the same seed gives the same bits).
    rate : float, optional
        Sample rate of the recording, Hz (default: the scenario's).
    overrides, **keys
        Scenario overrides, as for :func:`simulate`.
    """

    def __init__(
        self, scenario="e2", *, particles=1000, noise=None, seed=1, rate=None, overrides=None, **keys
    ):
        particles = _count("particles", particles, 1)
        seed = _count("seed", seed, 0)
        if rate is not None:
            rate = _number("rate", rate)
        values = _channels("noise", noise if noise is not None else {})
        self._inner = _vibrissa.Filter(
            _scenario(scenario), _overrides(overrides, keys), values, particles, seed, rate
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
    def period(self):
        """The sample period, s."""
        return self._inner.period

    @property
    def noise(self):
        """The sensor noise per channel the filter assumes, SI."""
        return self._inner.noise

    @property
    def counts(self):
        """Particle steps, diverged steps (0 expected), moves undone and resamplings so far."""
        return self._inner.counts
