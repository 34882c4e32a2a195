"""Running work at once: numba kernels on threads (:mod:`.threads`) and independent jobs in worker
processes (:mod:`.parallel`)."""
