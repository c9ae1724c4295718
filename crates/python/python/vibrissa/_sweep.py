"""Sweeps: every combination of a grid of scenario values, as ``vibrissa sweep`` runs them.

The plan (the runs, their file names, which are finished already) and each run's files and the
manifest are made by the same code as the command line's, so a sweep from Python, on threads or
on a Ray cluster (:mod:`vibrissa.ray`), writes the same files as ``vibrissa sweep``.
"""

import math
import os
import sys
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor, as_completed

from . import _vibrissa

FORMATS = ("csv", "npy", "npz")


def grid_texts(grid):
    """``grid`` as the command line's ``--grid`` texts.

    A mapping of keys to a list of values (``{"d": [0.015, 0.02]}``) or to a range text
    (``{"d": "0.015:0.03:16"}``: 16 values from 0.015 to 0.03), a list of ``key=...`` texts, or
    ``None`` (a built-in experiment's own grid).
    """
    from . import _value

    if grid is None:
        return []
    if isinstance(grid, str):
        return [grid]
    if isinstance(grid, Mapping):
        texts = []
        for key, values in grid.items():
            if not isinstance(key, str):
                raise TypeError(f"grid: keys are scenario keys (str), not {key!r}")
            if isinstance(values, str):
                texts.append(f"{key}={values}")
                continue
            try:
                values = list(values)
            except TypeError:
                raise TypeError(
                    f"grid[{key!r}]: expected a list of values or a 'start:stop:count' text, "
                    f"not {type(values).__name__}"
                ) from None
            if not values:
                raise ValueError(f"grid[{key!r}]: no values")
            texts.append(f"{key}=" + ",".join(_value(key, v) for v in values))
        return texts
    if isinstance(grid, (list, tuple)) and all(isinstance(g, str) for g in grid):
        return list(grid)
    raise TypeError(
        "grid: expected a mapping of scenario keys to values, or a list of 'key=...' texts, "
        f"not {type(grid).__name__}"
    )


class Plan:
    """The runs of a sweep of ``scenario`` over ``grid`` (see :func:`vibrissa.sweep`)."""

    def __init__(self, scenario, grid, out, format, overrides, keys):
        from . import _overrides, _scenario

        if format not in FORMATS:
            raise ValueError(f"format = {format!r}: choose one of {', '.join(FORMATS)}")
        self.scenario = _scenario(scenario)
        self.sets = _overrides(overrides, keys)
        self.out = None if out is None else os.fspath(out)
        if self.out is not None:
            os.makedirs(self.out, exist_ok=True)
        self.keys, jobs = _vibrissa.sweep_plan(
            self.scenario, self.sets, grid_texts(grid), format, self.out
        )
        self.files = [j[0] for j in jobs]
        self.params = [j[1] for j in jobs]
        self.done = [j[2] for j in jobs]

    def __len__(self):
        return len(self.files)

    def sets_of(self, k):
        """The overrides of run ``k``: the sweep's, then its grid values."""
        return self.sets + [f"{key}={value}" for key, value in self.params[k]]

    def values(self, k):
        """Run ``k``'s grid values, numbers as floats."""
        out = {}
        for key, value in self.params[k]:
            try:
                out[key] = float(value)
            except ValueError:
                out[key] = value
        return out

    def label(self, k):
        return " ".join(f"{key}={value}" for key, value in self.params[k])

    def first_rows(self):
        """The manifest's rows before anything runs: finished runs keep an earlier manifest's
        figures (NaN where it lacks them)."""
        previous = _vibrissa.sweep_previous(self.out)
        unknown = ("NaN",) * 4
        return [previous.get(f, unknown) if d else None for f, d in zip(self.files, self.done)]

    def write_manifest(self, rows):
        return _vibrissa.sweep_manifest(
            self.out, self.keys, list(zip(self.files, self.params)), rows
        )


# Runs stepped together at most (the simulator's lane width).
LANE_GROUP = 16


class SweepError(RuntimeError):
    """Runs of a sweep failed; ``failures`` lists ``(parameters, message)`` of each, and the
    other runs' files and the manifest are written."""

    def __init__(self, message, failures):
        super().__init__(message)
        self.failures = failures


def finish(plan, rows, failures, ran, skipped):
    """Writes the final manifest and returns the summary (raises :class:`SweepError` when runs
    failed)."""
    manifest = plan.write_manifest(rows)
    failures.sort()
    summary = {
        "runs": len(plan),
        "ran": ran,
        "skipped": skipped,
        "failed": [(plan.label(k), m) for k, m in failures],
        "manifest": manifest,
        "out": plan.out,
    }
    if failures:
        which = "; ".join(plan.label(k) for k, _ in failures)
        raise SweepError(
            f"{len(failures)} of {len(plan)} runs failed ({which}); the other runs are in "
            f"`{plan.out}`",
            summary["failed"],
        )
    return summary


def sweep(
    scenario="e2",
    grid=None,
    out=None,
    *,
    format="csv",
    jobs=None,
    progress=False,
    overrides=None,
    **keys,
):
    """Run every combination of ``grid``'s values of ``scenario``, as ``vibrissa sweep``.

    Parameters
    ----------
    scenario : str or os.PathLike
        A built-in name or the path of a scenario file.
    grid : mapping, list of str, or None
        The keys to vary: ``{"d": [0.015, 0.02], "v": "0.3:1.5:5"}`` (a list of values, or
        ``start:stop:count``), or ``["d=0.015,0.02"]`` as on the command line. ``None`` sweeps
        a built-in experiment's own grid (e2: d = 15…30 mm × v = 0.3…1.5 m/s, 80 runs).
    out : str or os.PathLike, optional
        A folder: each run's series and sidecar are written there with ``manifest.csv``, as the
        command line writes them, and runs already finished there are skipped (resume). Without
        it, the runs come back as arrays.
    format : "csv", "npy" or "npz"
        File format of the runs (with ``out``).
    jobs : int, optional
        Runs at a time (threads; default one per core).
    progress : bool
        Print a line on standard error as each run finishes.
    overrides, **keys
        Overrides of the scenario for every run, as for :func:`vibrissa.simulate`.

    Returns
    -------
    list of dict, or dict
        Without ``out``: per run, in the grid's order (the first key varies slowest),
        ``{"params": {key: value}, "file": name, "run": {column: array}}``. With ``out``: a
        summary ``{"runs", "ran", "skipped", "failed", "manifest", "out"}``.

    Raises
    ------
    SweepError
        Some runs failed (after the others ran and the manifest was written).
    ValueError, TypeError
        A malformed grid, an unknown key or value, as the command line's messages.
    """
    from . import _count

    plan = Plan(scenario, grid, out, format, overrides, keys)
    workers = (os.cpu_count() or 1) if jobs is None else _count("jobs", jobs, 1)
    if out is None:
        def one(k):
            columns = _vibrissa.simulate(plan.scenario, plan.sets_of(k))
            return {
                "params": plan.values(k),
                "file": plan.files[k],
                "run": dict(columns),
            }

        with ThreadPoolExecutor(max_workers=workers) as pool:
            return list(pool.map(one, range(len(plan))))

    rows = plan.first_rows()
    plan.write_manifest(rows)
    todo = [k for k in range(len(plan)) if not plan.done[k]]
    skipped = len(plan) - len(todo)
    if skipped and progress:
        print(f"skipping {skipped} of {len(plan)} runs: already in `{plan.out}`", file=sys.stderr)
    failures = []
    ran = 0
    # A few runs per task, so that runs of one whisker step together in lanes (each to the bits
    # it reaches alone): full lane groups, unless there are too few runs for every worker.
    size = max(1, min(LANE_GROUP, -(-len(todo) // workers)))
    parts = [todo[i : i + size] for i in range(0, len(todo), size)]
    done = 0
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {
            pool.submit(
                _vibrissa.sweep_run_batch,
                plan.scenario,
                plan.sets,
                [(plan.files[k], plan.params[k]) for k in part],
                plan.out,
            ): part
            for part in parts
        }
        for future in as_completed(futures):
            for k, (figures, error) in zip(futures[future], future.result()):
                done += 1
                if error is None:
                    rows[k] = figures
                    ran += 1
                else:
                    failures.append((k, error))
                if progress:
                    print(f"{done}/{len(todo)} runs", file=sys.stderr)
            plan.write_manifest(rows)
    return finish(plan, rows, failures, ran, skipped)


def chunks(items, size):
    """``items`` in consecutive lists of ``size``."""
    return [items[i : i + size] for i in range(0, len(items), size)]


def chunk_size(count, workers):
    """Runs per task: about four tasks per worker, so that the load evens out."""
    return max(1, math.ceil(count / (4 * max(1, workers))))
