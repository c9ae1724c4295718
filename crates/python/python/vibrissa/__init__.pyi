import os
from typing import Any, Mapping, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str
COLUMNS: tuple[str, ...]

Value = Union[bool, float, int, str, Sequence[Union[bool, float, int, str]]]

def builtins() -> list[str]: ...
def simulate(
    scenario: Union[str, os.PathLike[str]] = "e2",
    *,
    overrides: Mapping[str, Value] | None = None,
    as_frame: bool = False,
    **keys: Value,
) -> Union[dict[str, npt.NDArray[np.float64]], Any]: ...
