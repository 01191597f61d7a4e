"""The task suite: satisfiable specs with witness controllers (bench/suite/README.md)."""

from bench.suite.tasks import (
    FAMILIES,
    Rollouts,
    Task,
    load_tasks,
    nested_intervals,
    rollout,
    spread,
    task,
    zero_input,
)

__all__ = ["FAMILIES", "Rollouts", "Task", "load_tasks", "nested_intervals", "rollout", "spread", "task", "zero_input"]
