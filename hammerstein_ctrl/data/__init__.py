"""Records: the validated input/output record, reading a user's own files, and the measures of fit.

The lowest public layer: it imports nothing of the package but its foundation.

.. autosummary::
   :nosignatures:

   IOData
   read_record
   DataNotFoundError
   sse
   rmse
   nrmse
   fit_percent
   fit_report
   channel_report
"""

from ._iodata import IOData
from ._records import read_record, DataNotFoundError
from ._metrics import sse, rmse, nrmse, fit_percent, fit_report, channel_report

__all__ = [
    "IOData", "read_record", "DataNotFoundError", "sse", "rmse", "nrmse", "fit_percent", "fit_report",
    "channel_report"
]
