"""Getting the robot to a target: candidate targets, path planning, path following, replanning and
the safety layer; the macro-action executor composes them (:mod:`.executor`)."""
