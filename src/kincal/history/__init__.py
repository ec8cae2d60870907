"""A robot over its life: the calibration store (SQLite or PostgreSQL, versioned schema, every write a
transaction), the records of calibrations, evaluations, checks, comparisons and events, where the store is
configured, each step between calibrations judged by kincal compare's test with its largest parameter
differences, and the history plot (matplotlib loads only when drawn). SQLAlchemy loads when a store is opened."""
from .changes import LISTED, Move, Step, calibrated, changed_parameters, largest, moves, not_compared, steps
from .plot import history_figure, save_history_figure
from .records import (KINDS, Identity, InputFile, Record, calibration_record, evaluation_record, event_record,
                      fingerprint, model_hash, not_in_future, parse_time, utc_time)
from .store import SCHEMA_VERSION, Store, StoreError, migrate, open_store
from .where import ENV, config_path, how_to_set, store_url

__all__ = ["Identity", "InputFile", "Record", "KINDS", "calibration_record", "evaluation_record", "event_record",
           "fingerprint", "model_hash", "utc_time", "parse_time", "not_in_future", "Store", "StoreError", "open_store",
           "migrate", "SCHEMA_VERSION", "store_url", "config_path", "how_to_set", "ENV", "history_figure",
           "save_history_figure", "changed_parameters", "moves", "largest", "not_compared", "steps", "calibrated", "Move",
           "Step", "LISTED"]
