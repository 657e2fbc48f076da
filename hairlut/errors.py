"""Typed exceptions raised by hairlut.

Every error names what was wrong: a parameter error names the field and the
value, an asset error names the file and the fault.  The CLI turns any
:class:`HairlutError` into one line on stderr and exit status 2.
"""

from __future__ import annotations

import os


class HairlutError(Exception):
    """Base class of every error hairlut raises on purpose."""


class ValidationError(HairlutError, ValueError):
    """A parameter is out of range, of the wrong type or missing."""

    def __init__(self, field: str, value: object, reason: str):
        self.field, self.value, self.reason = field, value, reason
        shown = repr(value)
        if len(shown) > 80:
            shown = shown[:77] + "..."
        super().__init__(f"{field}={shown}: {reason}")


class AssetError(HairlutError):
    """A table or image file cannot be used; the message names file and fault."""

    def __init__(self, path: str | os.PathLike, fault: str):
        self.path, self.fault = os.fspath(path), fault
        super().__init__(f"{self.path}: {fault}")


class AssetNotFoundError(AssetError, FileNotFoundError):
    """The file does not exist."""


class FormatError(AssetError):
    """The file is not HDF5 / not OpenEXR (wrong signature)."""


class CorruptAssetError(AssetError):
    """The file has the right signature but its contents cannot be trusted."""


class TruncatedAssetError(CorruptAssetError):
    """The file is shorter than its own header says."""


class ChecksumError(CorruptAssetError):
    """Stored data fail their checksum (HDF5 fletcher32 or hairlut pixel hash)."""


class SchemaError(AssetError):
    """The file's ``hairlut_schema`` is not one this version can read."""


class KindError(AssetError):
    """The file holds a different kind of table than the caller asked for."""


class MissingDependencyError(AssetError):
    """Reading or writing this file needs an optional package that is not installed."""


class MissingDatasetError(AssetError):
    """A dataset, axis or channel that the kind requires is absent."""


class ForeignReferenceError(CorruptAssetError):
    """The file reaches outside itself: external raw storage, an external link, or a
    virtual dataset whose sources are not the asset's own parts."""


class ResourceError(HairlutError):
    """A request would need more memory (or disk) than allowed; the message gives the estimate."""


class BudgetError(ValidationError, ResourceError):
    """A scene or recipe key asks for more memory than the budget (``hairlut.budget``) allows."""

    def __init__(self, field: str, value: object, reason: str, estimate: int = 0, limit: int = 0):
        self.estimate, self.limit = int(estimate), int(limit)
        super().__init__(field, value, reason)


class AssetTooLargeError(AssetError, ResourceError):
    """A file declares tables larger than the memory budget allows to read."""


class DiskFullError(AssetError, ResourceError):
    """Writing the file failed for lack of space (ENOSPC, EDQUOT, EFBIG); nothing was left under its name."""


class DistributedError(HairlutError):
    """A process of a distributed bake cannot go on: the message names this process, the peer and the cause."""

    def __init__(self, index: int, count: int, cause: str):
        self.index, self.count, self.cause = int(index), int(count), cause
        super().__init__(f"distributed: process {self.index} of {self.count}: {cause}")


class NonFiniteError(HairlutError, ArithmeticError):
    """A computation produced NaN or infinity; the message names the inputs (recipe keys) that drive it."""


class BoundsError(HairlutError, ArithmeticError):
    """A computation produced finite values beyond their physical bounds (re > α, α outside [0, 1], ...): refused
    like NaN (NonFiniteError); the message names the table, the bound, the worst value and the recipe keys."""


__all__ = [
    "HairlutError",
    "ValidationError",
    "AssetError",
    "AssetNotFoundError",
    "FormatError",
    "CorruptAssetError",
    "TruncatedAssetError",
    "ChecksumError",
    "SchemaError",
    "KindError",
    "MissingDatasetError",
    "MissingDependencyError",
    "ForeignReferenceError",
    "ResourceError",
    "BudgetError",
    "AssetTooLargeError",
    "DiskFullError",
    "DistributedError",
    "NonFiniteError",
    "BoundsError",
]
