"""Exception types raised by hammerstein_ctrl.

Every error the package raises on bad input derives from :class:`HammersteinError`
and from :class:`ValueError`, so ``except ValueError`` keeps working for callers
who do not care about the distinction.
"""

__all__ = ["HammersteinError", "DataError", "DataNotFoundError", "ParameterError", "UnknownNameError",
           "IdentificationWarning", "SimulationWarning", "ChannelWarning"]


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


class IdentificationWarning(UserWarning):
    """A finding about an identified model that leaves it usable but needs a look (the result's ``warnings``)."""


class ChannelWarning(UserWarning):
    """A record's channels were matched to a model's by position, not by name (one side has default names)."""


class SimulationWarning(UserWarning):
    """A simulation's output stopped being finite (an unstable model, or one whose state overflowed)."""


class CacheWarning(UserWarning):
    """Never issued since 0.2.0 (nothing is compiled or cached at run time); kept for one release so that code that
    filters it still runs (``hammerstein_ctrl.CacheWarning`` is deprecated)."""


class NativeBuildError(RuntimeError):
    """Never raised since 0.2.0 (the compiled core is built when the package is installed); kept for one release so
    that code that catches it still runs (``hammerstein_ctrl.NativeBuildError`` is deprecated)."""
