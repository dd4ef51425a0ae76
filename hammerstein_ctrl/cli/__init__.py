"""The ``hammerstein-ctrl`` command line.

.. autosummary::
   :nosignatures:

   main
"""

from ._main import main

__all__ = [
    "main"
]
