"""Robot log formats: CARMEN logs, read and written (:mod:`.carmen`)."""
