"""Several experiments of one rig in one fit.

Engineers record several runs of the same plant. Fitting them together, the
blocks (linear coefficients and nonlinearity parameters) are shared, while
each record keeps its own output offset and initial state, which depend on how
that run started and not on the plant. :func:`hammerstein_ctrl.fit`
takes a list of records and fits them this way (MATLAB's ``merge`` of
experiments); this module holds the two pieces it needs:

* :class:`RecordsStructure`: the parameter layout, the block parameters once
  and then each record's offset and initial state, named ``y0[k]``,
  ``xi0[k]``, ...;
* :class:`RecordsCost`: the sum of the records' squared output errors, with
  the least-squares protocol of a single-record cost (``residuals``,
  ``residuals_batch``, ``normal_equations``), so every optimiser, the
  uncertainty and the verdicts work on it unchanged.

The records must share the sampling time and the intersample behaviour; they
may differ in length. Each record is simulated from its own initial state: no
state carries over from one record to the next.

Examples
--------
>>> import numpy as np, control as ct
>>> from hammerstein_ctrl import IOData, HammersteinStructure, LinearStructure, Tanh
>>> s = HammersteinStructure(LinearStructure(0, 1), Tanh(), offset=True)
>>> rs = RecordsStructure(s, 2)
>>> rs.param_names
('a0', 'd0', 'd1', 'y0[0]', 'y0[1]')
>>> rs.local([1.0, 2.0, 0.5, 0.1, -0.2], 1).tolist()
[1.0, 2.0, 0.5, -0.2]
"""

from __future__ import annotations

import hashlib

import numpy as np

from .._checks import as_count
from ..exceptions import DataError, ParameterError
from ..data._iodata import IOData
from ..optimize._normal_equations import NormalEquations, point_and_steps
from ._delay_fit import DelayedCost
from ._objective import HammersteinCost
from ..blocks._structure import BlockStructure
from ._cost import StructureSized

__all__ = ["RecordsStructure", "RecordsCost", "concatenated", "duplicated_records"]


class RecordsStructure:
    """Parameter layout of a fit to ``n_records`` records of one plant.

    Parameters
    ----------
    structure : HammersteinStructure, WienerStructure or HammersteinWienerStructure
        The blocks, with the offset and initial-state options of every record.
    n_records : int
        How many records share the blocks.

    Attributes
    ----------
    base : BlockStructure
        ``structure`` itself: the layout of one record's beta.
    param_names : tuple of str
        The block parameters, then each record's offset and initial state
        with the record's index in brackets.
    """

    def __init__(self, structure: BlockStructure, n_records: int):
        if not isinstance(structure, BlockStructure):
            raise ParameterError("structure must be a HammersteinStructure, WienerStructure or "
                                 f"HammersteinWienerStructure, got {type(structure).__name__}")
        self.base = structure
        self.n_records = as_count(n_records, "n_records", minimum=1)
        core, extra = structure.n_core, structure.param_names[structure.n_core:]
        self.param_names: tuple[str, ...] = structure.core_names + tuple(
            f"{name}[{k}]" for k in range(self.n_records) for name in extra)
        self._index = [np.r_[0:core, core + k * len(extra):core + (k + 1) * len(extra)]
                       for k in range(self.n_records)]

    # the blocks are the base structure's
    linear = property(lambda self: self.base.linear)
    input_nonlinearity = property(lambda self: self.base.input_nonlinearity)
    output_nonlinearity = property(lambda self: self.base.output_nonlinearity)
    offset = property(lambda self: self.base.offset)
    initial_state = property(lambda self: self.base.initial_state)
    kind = property(lambda self: self.base.kind)
    core_names = property(lambda self: self.base.core_names)
    n_core = property(lambda self: self.base.n_core)

    def __getattr__(self, name):
        # what one record's layout knows and this class does not redefine (e.g. the verdicts' view of the
        # blocks) is the base structure's
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    @property
    def n_params(self) -> int:
        """Length of beta: the block parameters once, each record's offset and initial state."""
        return len(self.param_names)

    def check_beta(self, beta) -> np.ndarray:
        """beta as a float array of shape ``(n,)`` or ``(B, n)`` (a :class:`ParameterError` naming the layout)."""
        b = np.asarray(beta, dtype=float) if not isinstance(beta, np.ndarray) else beta.astype(float, copy=False)
        if b.ndim not in (1, 2) or b.shape[-1] != self.n_params:
            raise ParameterError(f"beta must have {self.n_params} entries {list(self.param_names)}, "
                                 f"got {b.shape[-1] if b.ndim else 'a scalar'}")
        return b

    def indices(self, record: int) -> np.ndarray:
        """Positions in beta of record ``record``'s own beta (the base structure's layout)."""
        return self._index[record]

    def local(self, beta, record: int = 0) -> np.ndarray:
        """Record ``record``'s beta in the base structure's layout."""
        return self.check_beta(beta)[..., self._index[record]]

    def glue(self, betas) -> np.ndarray:
        """The inverse of :meth:`local`: one beta from each record's (their block parameters must agree)."""
        betas = [self.base.check_beta(b) for b in betas]
        if len(betas) != self.n_records:
            raise ParameterError(f"give {self.n_records} record betas, got {len(betas)}")
        out = np.empty(self.n_params)
        for k, b in enumerate(betas):
            out[self._index[k]] = b
        return out

    def linear_params(self, beta) -> np.ndarray:
        return self.local(beta)[..., :self.linear.n_params]

    def input_params(self, beta):
        return self.base.input_params(self.local(beta))

    def output_params(self, beta):
        return self.base.output_params(self.local(beta))

    def nuisance(self, beta, record: int = 0):
        """``(offset, initial_state)`` of record ``record``."""
        return self.base.nuisance(self.local(beta, record))

    def model(self, beta, record: int = 0, **kwargs):
        """The model of record ``record`` (its offset and initial state): ``kwargs`` as the base structure's."""
        return self.base.model(self.local(beta, record), **kwargs)

    def normalize(self, beta) -> np.ndarray:
        """beta with the nonlinearities' parameters in their canonical form (the models unchanged)."""
        b = np.array(self.check_beta(beta), dtype=float)
        b[..., :self.n_core] = self.base.normalize(self.local(b))[..., :self.n_core]
        return b

    def describe(self) -> str:
        return f"{self.base.describe()}, fitted to {self.n_records} records (offset and initial state per record)"

    def __repr__(self):
        return f"RecordsStructure({self.base!r}, {self.n_records})"


def _check_records(records) -> tuple:
    records = tuple(records)
    if not records:
        raise ParameterError("give at least one record")
    for k, rec in enumerate(records):
        if not isinstance(rec, IOData):
            raise ParameterError(f"record {k} must be an IOData record, got {type(rec).__name__}")
    first = records[0]
    for k, rec in enumerate(records[1:], 1):
        if not np.isclose(rec.dt, first.dt, rtol=1e-9, atol=0.0):
            raise DataError(f"record {k} ({rec.name!r}) has sampling time {rec.dt:g} s, record 0 ({first.name!r}) "
                            f"{first.dt:g} s: records fitted together must share it (resample one of them)")
        if rec.intersample != first.intersample:
            raise DataError(f"record {k} ({rec.name!r}) holds its input by {rec.intersample!r}, record 0 by "
                            f"{first.intersample!r}: records fitted together must share the intersample behaviour")
    return records


def concatenated(records) -> IOData:
    """The records end to end as one IOData (for statistics over all samples, not for simulation)."""
    records = _check_records(records)
    first = records[0]
    return IOData(np.concatenate([r.u for r in records]), np.concatenate([r.y for r in records]), dt=first.dt,
                  name=" + ".join(r.name for r in records), input_name=first.input_name,
                  output_name=first.output_name, input_unit=first.input_unit, output_unit=first.output_unit,
                  intersample=first.intersample)


class RecordsCost(StructureSized):
    """Sum of squared output errors of one block structure over several records.

    Parameters
    ----------
    records : sequence of IOData
        Records of one plant with the same sampling time and intersample behaviour.
    structure : BlockStructure
        The blocks and each record's nuisance options (offset, initial state).
    reject_unstable : bool, default False
        As :class:`~hammerstein_ctrl.fit.HammersteinCost`.

    Attributes
    ----------
    records : tuple of IOData
    structure : RecordsStructure
    costs : tuple of HammersteinCost or DelayedCost
        One per record, in the base structure's layout (a :class:`~hammerstein_ctrl.fit.DelayedCost`
        when the blocks have a dead time, which the records share).
    data : IOData
        The records end to end (:func:`concatenated`): what statistics over all samples use.

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import IOData, HammersteinStructure, LinearStructure, Tanh
    >>> from hammerstein_ctrl.fit import HammersteinCost
    >>> t = np.arange(200) * 0.05
    >>> r1 = IOData(np.sin(t), np.cos(t), dt=0.05, name="a")
    >>> r2 = IOData(np.cos(t), np.sin(t), dt=0.05, name="b")
    >>> s = HammersteinStructure(LinearStructure(0, 1), Tanh(), offset=True)
    >>> cost = RecordsCost([r1, r2], s)
    >>> beta = [1.0, 2.0, 0.5, 0.1, -0.2]
    >>> single = HammersteinCost(r1, s)([1.0, 2.0, 0.5, 0.1]) + HammersteinCost(r2, s)([1.0, 2.0, 0.5, -0.2])
    >>> bool(np.isclose(cost(beta), single))
    True
    """

    def __init__(self, records, structure: BlockStructure, *, reject_unstable: bool = False):
        self.records = _check_records(records)
        self.structure = RecordsStructure(structure, len(self.records))
        self.reject_unstable = bool(reject_unstable)
        single = DelayedCost if structure.linear.delay else HammersteinCost      # a dead time: exact delayed passes
        self.costs = tuple(single(r, structure, reject_unstable=reject_unstable) for r in self.records)
        self.data = concatenated(self.records)
        self._bounds = np.cumsum([0] + [len(r) for r in self.records])

    @property
    def n_samples(self) -> int:
        """Samples of all records together."""
        return int(self._bounds[-1])

    def __call__(self, beta) -> float:
        """J at one beta: the sum over the records (``inf`` if any record's simulation fails)."""
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        return float(sum(c(self.structure.local(b, k)) for k, c in enumerate(self.costs)))

    def batch(self, betas) -> np.ndarray:
        """J for each row of ``betas``."""
        b = np.atleast_2d(self.structure.check_beta(betas))
        return np.sum([c.batch(self.structure.local(b, k)) for k, c in enumerate(self.costs)], axis=0)

    def residuals(self, beta) -> np.ndarray:
        """``y - yhat`` of every record, end to end."""
        b = self.structure.check_beta(beta)
        return np.concatenate([c.residuals(self.structure.local(b, k)) for k, c in enumerate(self.costs)])

    def residuals_batch(self, betas) -> np.ndarray:
        """Residual vectors (rows) of a batch, the records end to end."""
        b = np.atleast_2d(self.structure.check_beta(betas))
        return np.hstack([c.residuals_batch(self.structure.local(b, k)) for k, c in enumerate(self.costs)])

    def simulate(self, beta) -> np.ndarray:
        """Simulated outputs of every record (each from its own state), end to end."""
        return np.concatenate(self.simulate_records(beta))

    def simulate_records(self, beta) -> list:
        """Simulated output of each record."""
        b = self.structure.check_beta(beta)
        return [c.simulate(self.structure.local(b, k)) for k, c in enumerate(self.costs)]

    def split(self, signal) -> list:
        """A signal over all records (such as :meth:`residuals`) cut into one piece per record."""
        return [signal[a:b] for a, b in zip(self._bounds[:-1], self._bounds[1:])]

    def pass_evaluations(self) -> int:
        """Evaluations (simulations of every record) one :meth:`normal_equations` pass costs: a record's pass
        differences only the shared blocks and its own nuisances, so the pass costs one record's ``p + 1``."""
        return self.structure.base.n_params + 1

    def normal_equations(self, beta, steps=None) -> NormalEquations:
        """``r @ r``, ``J.T @ r`` and ``J.T @ J`` over all records, from each record's compiled pass.

        A record's sums involve only the block parameters and its own offset
        and initial state; they are added into the rows and columns of those.
        """
        b, h = point_and_steps(self.structure, beta, steps)
        fun, gradient, gram = 0.0, np.zeros(b.size), np.zeros((b.size, b.size))
        for k, cost in enumerate(self.costs):
            idx = self.structure.indices(k)
            ne = cost.normal_equations(b[idx], h[idx])
            fun += ne.fun
            gradient[idx] += ne.gradient
            gram[np.ix_(idx, idx)] += ne.gram
        return NormalEquations(float(fun), gradient, gram, h)

    def __repr__(self):
        return f"RecordsCost({len(self.records)} records, {self.n_samples} samples, {self.structure.base!r})"


def duplicated_records(records) -> list[tuple[int, ...]]:
    """Groups of records (their indices) that hold the same samples: the same ``dt``, ``u`` and ``y``.

    A record passed twice counts its noise twice, which makes every
    standard error too small (by ``sqrt(2)`` for one copy).

    Examples
    --------
    >>> import numpy as np
    >>> a = IOData(np.arange(5.0), np.ones(5), dt=0.1, name="a")
    >>> b = IOData(np.arange(5.0), np.ones(5) * 2, dt=0.1, name="b")
    >>> duplicated_records([a, b, a])
    [(0, 2)]
    """
    groups: dict = {}
    for k, rec in enumerate(records):
        digest = hashlib.blake2b(digest_size=16)
        for signal in (rec.u, rec.y):
            digest.update(np.ascontiguousarray(signal, dtype=float).tobytes())
        groups.setdefault((len(rec), float(rec.dt), digest.digest()), []).append(k)
    return [tuple(g) for g in groups.values() if len(g) > 1]

