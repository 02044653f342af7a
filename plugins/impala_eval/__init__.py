"""Mission evaluation: trajectory metrics against the truth, reports and plots."""

from .evaluator import TrajectoryEvaluator
from .metrics import TrajectoryMetrics, rigid_align_2d, trajectory_metrics
from .report import format_metrics, load_metrics, write_report

__all__ = ["TrajectoryEvaluator", "TrajectoryMetrics", "trajectory_metrics", "rigid_align_2d", "write_report",
           "format_metrics", "load_metrics"]
