"""emmi-gym: active-SLAM environments with the EMMI certainty reward (Blanco et al., IROS 2006)."""

__version__ = "0.1.0"
