"""Training runs' folders (:class:`RunFolder`): what a run writes and the checks it makes before it writes
anything (:mod:`.folder`), its record ``training.yaml`` (:mod:`.training_record`), its model files
(:mod:`.model_files`) and what a resumed run may change of its configuration (:mod:`.config_changes`)."""

from .folder import RUN_FILES, RunError, RunFolder, RunStart, WarmStart

__all__ = ["RUN_FILES", "RunError", "RunFolder", "RunStart", "WarmStart"]
