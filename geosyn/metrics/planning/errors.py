"""Errors of the motion planner (`geosyn.metrics.planning`)."""

from __future__ import annotations

from geosyn.core.errors import InvalidArgument
from geosyn.metrics.errors import MetricError

__all__ = ["GoalUnreachable", "InCollision", "NoPathFound", "OutsideJointLimits", "PlanningError"]


class PlanningError(MetricError):
    """Base class of the planner's errors."""


class OutsideJointLimits(PlanningError, InvalidArgument):
    """The start or goal lies outside the robot's position limits.

    Attributes:
        which: ``"start"`` or ``"goal"``.
        joints: indices of the joints outside their limits.
    """

    def __init__(self, message: str, which: str, joints: tuple[int, ...]) -> None:
        super().__init__(message)
        self.which = which
        self.joints = joints


class InCollision(PlanningError, InvalidArgument):
    """The start or goal configuration collides with an obstacle.

    Attributes:
        which: ``"start"`` or ``"goal"``.
        obstacle: index of the obstacle with the deepest penetration.
        sphere: index of the robot collision sphere that penetrates it.
        joint: name of the joint carrying that sphere.
        clearance: its (negative) clearance [m].
    """

    def __init__(
        self, message: str, which: str, obstacle: int, sphere: int, joint: str, clearance: float
    ) -> None:
        super().__init__(message)
        self.which = which
        self.obstacle = obstacle
        self.sphere = sphere
        self.joint = joint
        self.clearance = float(clearance)


class NoPathFound(PlanningError):
    """No collision-free path was found within the time budget.

    Attributes:
        budget: the time budget [s].
        elapsed: the time spent [s].
        attempts: one line per method tried and how it ended.
    """

    def __init__(
        self, message: str, budget: float, elapsed: float, attempts: tuple[str, ...]
    ) -> None:
        super().__init__(message)
        self.budget = float(budget)
        self.elapsed = float(elapsed)
        self.attempts = attempts

    @classmethod
    def after(cls, budget: float, elapsed: float, attempts: tuple[str, ...]) -> NoPathFound:
        """The refusal of a query of ``budget`` [s] that spent ``elapsed`` [s] on
        ``attempts``, with what to try next."""
        return cls(
            f"no collision-free path from the start to the goal within the {budget:g} s "
            f"budget ({elapsed:.2f} s spent): " + "; ".join(attempts) + ". Try a larger "
            "budget, a smaller margin, or check that the goal is reachable (not enclosed "
            "by obstacles)",
            budget, elapsed, attempts,
        )  # fmt: skip


class GoalUnreachable(PlanningError):
    """No configuration reaches an end-effector goal within its tolerances, inside the
    joint limits and clear of the scene.

    Attributes:
        frame: the goal frame.
        position: (3,) the goal position [m].
        refused: why each solution found was refused (collision, self-collision).
    """

    def __init__(
        self, message: str, frame: str, position: tuple[float, ...], refused: tuple[str, ...]
    ) -> None:
        super().__init__(message)
        self.frame = frame
        self.position = tuple(position)
        self.refused = refused
