"""Exception types raised by hammerstein_ctrl.

Every error the package raises on bad input derives from :class:`HammersteinError`
and from :class:`ValueError`, so ``except ValueError`` keeps working for callers
who do not care about the distinction.
"""

__all__ = ["HammersteinError", "DataError", "DataNotFoundError", "ParameterError", "UnknownNameError", "CacheWarning",
           "IdentificationWarning", "SimulationWarning", "NativeBuildError"]


class HammersteinError(ValueError):
    """Base class of every input error raised by hammerstein_ctrl."""


class DataError(HammersteinError):
    """Measured data are unusable (NaN, mismatched lengths, irregular time, ...)."""


class DataNotFoundError(DataError, FileNotFoundError):
    """A file to read (a record, a model, a result) could not be located."""


class ParameterError(HammersteinError):
    """A parameter vector has the wrong length, shape or values."""


class UnknownNameError(HammersteinError):
    """A method, nonlinearity or preset name is not known."""


class CacheWarning(UserWarning):
    """A compiled function's on-disk cache could not be read: it was compiled again and saved afresh."""


class IdentificationWarning(UserWarning):
    """A finding about an identified model that leaves it usable but needs a look (the result's ``warnings``)."""


class SimulationWarning(UserWarning):
    """A simulation's output stopped being finite (an unstable model, or one whose state overflowed)."""


class NativeBuildError(RuntimeError):
    """The package's C library could not be built on this machine (no C compiler, or the compiler failed): the
    message names the compiler and its first error line."""
