"""Physical models: vehicle dynamics, antenna patterns, channel, jammer, fading.

Pure functions and small dataclasses in SI units. Functions marked *dual* accept either numpy
arrays or CasADi symbols, so one definition serves the simulator and the optimizer.
"""
