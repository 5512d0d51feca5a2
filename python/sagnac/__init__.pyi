"""Type stubs of the sagnac package (see sagnac/__init__.py for the docs)."""
from os import PathLike
from typing import Any, Literal, Mapping, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
Unit = Literal["counts", "dph", "dps", "rad_s", "mps2", "g"]
DataType = Literal["phase", "freq"]
Taus = Union[None, Literal["all", "octave", "decade", "log10"], ArrayLike]
DevTuple = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]

def analyze(
    samples: Union[ArrayLike, Mapping[str, ArrayLike]],
    *,
    sample_rate_hz: float,
    unit: Union[Unit, Mapping[str, Unit], None] = None,
    pulse_arcsec: float | None = None,
    axes: Sequence[str] | None = None,
    raw_statistics: bool = False,
) -> dict[str, Any]: ...
def allan(
    data: ArrayLike,
    *,
    tau0: float,
    data_type: Literal["phase", "freq", "counts"] = "phase",
    stat: Literal["adev", "oadev", "mdev", "hdev", "ohdev", "totdev"] = "oadev",
    taus: Union[Literal["octave", "decade", "all"], ArrayLike] = "octave",
    confidence: float = 0.683,
) -> dict[str, Any]: ...
def oadev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def adev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def mdev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def hdev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def ohdev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def totdev(data: ArrayLike, rate: float = 1.0, data_type: DataType = "phase", taus: Taus = None) -> DevTuple: ...
def simulate(model: Union[str, PathLike[str]], duration_s: float, seed: int) -> dict[str, Any]: ...
def read(path: Union[str, PathLike[str]], **input_options: Any) -> dict[str, Any]: ...
def diagnose(model: Union[str, PathLike[str]], recording: Union[str, PathLike[str]], **options: Any) -> dict[str, Any]: ...
