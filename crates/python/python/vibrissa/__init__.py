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

import math
import os
from numbers import Real

from . import _vibrissa

__all__ = ["simulate", "builtins", "COLUMNS", "__version__"]
__version__ = _vibrissa.__version__

#: The columns of a run, in order: time (s), the first two joint angles (rad), the base moment
#: (N·m) and force (N), whether the whisker touches an object (1 or 0), the contact point
#: (m, world frame) and its arc length from the base (m; NaN without contact).
COLUMNS = ("t", "theta01", "theta12", "m0", "fx", "fy", "contact", "cx", "cy", "s")


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
    scenario : str or os.PathLike
        A built-in name (``"e1"``, ``"e2"``) or the path of a TOML scenario file.
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
    columns = _vibrissa.simulate(_scenario(scenario), _overrides(overrides, keys))
    if as_frame:
        try:
            import pandas
        except ImportError as e:
            raise ImportError("as_frame=True needs pandas: pip install pandas") from e
        return pandas.DataFrame({name: columns[name] for name in COLUMNS})
    return {name: columns[name] for name in COLUMNS}
