"""Geometry shared by the simulator and the filter: the cell grid (:mod:`.grid`) and the odometry
motion model (:mod:`.motion`)."""
