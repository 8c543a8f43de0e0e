"""Missions, closed-loop simulation and disturbances."""
