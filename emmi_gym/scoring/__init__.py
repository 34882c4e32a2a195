"""Scores against ground truth, which the agent never sees: trajectory error, map accuracy, and the
oracle map with the scores against it (:mod:`.scores`, :mod:`.oracle`)."""
