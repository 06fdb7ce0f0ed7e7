"""Deprecated: the obstacle terms of a shaped metric, for `geosyn.experiments.build`
until it passes ``GeodesicMPC(obstacles=...)``; use
`geosyn.controllers.mpc.ocp.obstacles` (the MPC's obstacle slots of world shapes)."""

from __future__ import annotations

from geosyn.controllers.mpc.ocp.obstacles import metric_obstacle_terms as find_obstacle_terms

__all__ = ["find_obstacle_terms"]
