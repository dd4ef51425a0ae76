"""Exception types raised by hammerstein_ctrl.

Every error the package raises on bad input derives from :class:`HammersteinError`
and from :class:`ValueError`, so ``except ValueError`` keeps working for callers
who do not care about the distinction.
"""

__all__ = ["HammersteinError", "DataError", "DataNotFoundError", "ParameterError", "UnknownNameError",
           "IdentificationWarning", "SimulationWarning", "ChannelWarning"]


class HammersteinError(ValueError):
    """Base class of every input error raised by hammerstein_ctrl.

    Examples
    --------
    >>> issubclass(DataError, HammersteinError) and issubclass(ParameterError, HammersteinError)
    True
    """


class DataError(HammersteinError):
    """Measured data are unusable (NaN, mismatched lengths, irregular time, ...).

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> try:
    ...     hc.IOData([1.0, 2.0], [1.0], dt=0.1)
    ... except DataError as exc:
    ...     print(type(exc).__name__)
    DataError
    """


class DataNotFoundError(DataError, FileNotFoundError):
    """A file to read (a record, a model, a result) could not be located."""


class ParameterError(HammersteinError):
    """A parameter vector has the wrong length, shape or values.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> try:
    ...     hc.LinearStructure(0, 0)
    ... except ParameterError as exc:
    ...     print(type(exc).__name__)
    ParameterError
    """


class UnknownNameError(HammersteinError):
    """A method, nonlinearity or preset name is not known.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> try:
    ...     hc.nonlinearity_from_name("cubic-ish")
    ... except UnknownNameError as exc:
    ...     print(type(exc).__name__)
    UnknownNameError
    """


class IdentificationWarning(UserWarning):
    """A finding about an identified model that leaves it usable but needs a look (the result's ``warnings``).

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("a pole far beyond the record's bandwidth", IdentificationWarning)
    >>> caught[0].category.__name__
    'IdentificationWarning'
    """


class ChannelWarning(UserWarning):
    """A record's channels were matched to a model's by position, not by name (one side has default names).

    Examples
    --------
    >>> issubclass(ChannelWarning, UserWarning)
    True
    """


class SimulationWarning(UserWarning):
    """A simulation's output stopped being finite (an unstable model, or one whose state overflowed).

    Examples
    --------
    >>> import warnings, numpy as np, hammerstein_ctrl as hc
    >>> m = hc.HammersteinModel(([1.0], [1.0, -50.0]), hc.Polynomial(1), [1.0])       # a pole at +50 rad/s
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = m.simulate(np.arange(2000) * 0.1, np.ones(2000))
    >>> any(w.category is SimulationWarning for w in caught)
    True
    """


class CacheWarning(UserWarning):
    """Never issued since 0.2.0 (nothing is compiled or cached at run time); kept for one release so that code that
    filters it still runs (``hammerstein_ctrl.CacheWarning`` is deprecated)."""


class NativeBuildError(RuntimeError):
    """Never raised since 0.2.0 (the compiled core is built when the package is installed); kept for one release so
    that code that catches it still runs (``hammerstein_ctrl.NativeBuildError`` is deprecated)."""
