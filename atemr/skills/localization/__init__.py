"""Localization: scan matching (ICP, scan-to-map), AMCL, EKF odometry fusion and the covariance monitor.

Every module is a pure skill: arrays and messages in, estimates out, time passed in as ``now``, random
draws from a `numpy.random.Generator` the caller owns. See each module's docstring for the maths.
"""
