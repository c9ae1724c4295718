import os
from typing import Any, Mapping, Sequence, Union

from . import Grid, Value

def sweep(
    scenario: Union[str, os.PathLike[str]] = "e2",
    grid: Grid = None,
    out: Union[str, os.PathLike[str], None] = None,
    *,
    address: str | None = None,
    chunk: int | None = None,
    format: str = "csv",
    progress: bool = False,
    overrides: Mapping[str, Value] | None = None,
    **keys: Value,
) -> dict[str, Any]: ...
def main(argv: Sequence[str] | None = None) -> int: ...
