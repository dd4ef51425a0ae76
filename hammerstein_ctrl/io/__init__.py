"""Saving and loading models and identification results as versioned JSON.

.. autosummary::
   :nosignatures:

   save_model
   load_model
   save_result
   load_result
   load_saved
   SavedResult
   model_to_dict
   model_from_dict
   result_to_dict
   result_from_dict
   SCHEMA_VERSION
"""

from ._persistence import save_model, load_model, model_to_dict, model_from_dict, SCHEMA_VERSION
from ._results import save_result, load_result, load_saved, SavedResult, result_to_dict, result_from_dict

__all__ = [
    "save_model", "load_model", "save_result", "load_result", "load_saved", "SavedResult", "model_to_dict",
    "model_from_dict", "result_to_dict", "result_from_dict", "SCHEMA_VERSION"
]
