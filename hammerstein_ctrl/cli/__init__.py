"""The ``hammerstein-ctrl`` command line.

.. autosummary::
   :nosignatures:

   main
   build_parser
"""

from ._main import EXIT_ERROR, PROG, build_parser, main

__all__ = ["main", "build_parser", "EXIT_ERROR", "PROG"]
