"""Checking input at the boundary: the error that names a source, a field and what was expected
(:mod:`.errors`), typed and bounded option fields (:mod:`.validation`), the safe YAML reader
(:mod:`.yaml_files`), files to read and folders to write (:mod:`.paths`)."""
