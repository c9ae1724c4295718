import os
from typing import Any, Mapping, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str
COLUMNS: tuple[str, ...]
CHANNELS: tuple[str, ...]

Value = Union[bool, float, int, str, Sequence[Union[bool, float, int, str]]]

Scenario = Union[str, os.PathLike[str], Mapping[str, Any]]
Recording = Union[str, os.PathLike[str], Mapping[str, npt.ArrayLike], Any]

def builtins() -> list[str]: ...
def methods() -> list[str]: ...
def calibrate(
    scenario: Union[str, os.PathLike[str]],
    labelled: Union[str, os.PathLike[str]],
    out: Union[str, os.PathLike[str], None] = None,
    *,
    ignore_unlisted: bool = False,
    gain_prior: float | None = None,
    max_iterations: int | None = None,
    verbose: bool = False,
    overrides: Mapping[str, Value] | None = None,
    **keys: Value,
) -> dict[str, Any]: ...

Grid = Union[Mapping[str, Union[str, Sequence[Value]]], Sequence[str], None]

class SweepError(RuntimeError):
    failures: list[tuple[str, str]]

def sweep(
    scenario: Union[str, os.PathLike[str]] = "e2",
    grid: Grid = None,
    out: Union[str, os.PathLike[str], None] = None,
    *,
    format: str = "csv",
    jobs: int | None = None,
    progress: bool = False,
    overrides: Mapping[str, Value] | None = None,
    **keys: Value,
) -> Union[list[dict[str, Any]], dict[str, Any]]: ...
def estimate(
    obs: Union[Recording, Sequence[Recording]],
    scenario: Scenario = "e2",
    method: str = "krr-local",
    *,
    noise: Union[str, Mapping[str, float], None] = "auto",
    seed: int = 1,
    randomise: bool | None = None,
    particles: int | None = None,
    islands: int | None = None,
    check: bool = False,
    whisker: str | None = None,
    max_delay: float = 0.0,
    pool: bool | None = None,
    pool_rounds: int | None = None,
    overrides: Mapping[str, Value] | None = None,
    verbose: bool = False,
    whisker_from: Union[str, os.PathLike[str], None] = None,
    **keys: Value,
) -> Union[dict[str, Any], list[dict[str, Any]]]: ...
def estimate_shapes(
    obs: Union[Recording, Sequence[Recording]],
    shapes: Union[str, os.PathLike[str]] = "e3",
    *,
    whiskers: Sequence[str] | None = None,
    training: int = 800,
    noise: Union[str, Mapping[str, float], None] = "auto",
    seed: int = 1,
    randomise: bool = False,
    method: str = "shape-krr",
    verbose: bool = False,
    bank: int = 3200,
    whisker_from: Union[str, os.PathLike[str], None] = None,
    particles: int | None = None,
) -> Union[dict[str, Any], list[dict[str, Any]]]: ...
def simulate(
    scenario: Scenario = "e2",
    *,
    overrides: Mapping[str, Value] | None = None,
    as_frame: bool = False,
    **keys: Value,
) -> Union[dict[str, npt.NDArray[np.float64]], Any]: ...

class Filter:
    def __init__(
        self,
        scenario: Scenario = "e2",
        *,
        particles: int | None = None,
        noise: Mapping[str, float] | None = None,
        seed: int = 1,
        rate: float | None = None,
        randomise: bool | None = None,
        islands: int | None = None,
        overrides: Mapping[str, Value] | None = None,
        **keys: Value,
    ) -> None: ...
    def update(
        self, t: float, sample: Union[Mapping[str, float], Sequence[float]]
    ) -> dict[str, Any]: ...
    @property
    def posterior(self) -> dict[str, Any] | None: ...
    @property
    def trace(self) -> dict[str, npt.NDArray[np.float64]]: ...
    @property
    def unknowns(self) -> list[str]: ...
    @property
    def particles(self) -> int: ...
    @property
    def period(self) -> float: ...
    @property
    def noise(self) -> dict[str, float]: ...
    @property
    def counts(self) -> dict[str, int]: ...
