"""Studies: many independent runs of one scene over a grid of parameters and random
perturbations, summarised — ``contact-sim study STUDY.yaml`` or ``run_study``.

``spec`` is the study file (validation, grid and seeds), ``runner`` one run, ``execute`` the
executors (this process, a process pool, Ray) and ``runs.csv``, ``summary`` the per-cell table
and plot. Ray is imported only when a study is run with ``cluster=``.
"""
from .execute import run_study
from .runner import TIMING_COLUMNS, columns, run_one
from .spec import Study, list_studies, load_study, resolve_study, run_seed, studies_dir

__all__ = ["Study", "TIMING_COLUMNS", "columns", "list_studies", "load_study", "resolve_study", "run_one",
           "run_seed", "run_study", "studies_dir"]
