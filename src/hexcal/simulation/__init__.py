"""Monte Carlo simulation of calibration campaigns: one campaign protocol, one runner
that maps trials over an executor, and the seed paper's experiment and studies as
definitions over them. Imports every layer below (core to design).
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "MachineBatch": "campaign",
        "PaperExperiment": "campaign",
        "PoseStrategy": "study",
        "Progress": "campaign",
        "STRATEGIES": "study",
        "StudyCell": "study",
        "fixed_strategy": "study",
        "format_study": "study",
        "identify_batch": "campaign",
        "pose_errors": "campaign",
        "random_machines": "campaign",
        "run_paper_experiment": "campaign",
        "run_study": "study",
        "simulate_measurements": "campaign",
    },
)
