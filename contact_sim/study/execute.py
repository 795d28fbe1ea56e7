"""Running a study: the executors (in this process, a local process pool, Ray tasks) and the rows
written to ``runs.csv`` as each run completes.

Every executor is a generator of finished rows with a bounded number of runs in flight, so the
driver holds neither all the runs' futures nor their results: a study of any length runs in flat
memory, its rows on disk. Ray is imported only inside ``ray_rows``; neither the engine nor the node
imports it.
"""
import csv
import itertools
import math
import numbers
import os
import subprocess
import sys
import warnings

from ..errors import StudyError
from ..scene import load_scene
from .runner import columns, make_drive, run_one, run_scene
from .spec import load_study, run_seed
from .summary import summarise

#: runs in flight per worker (enough to keep every worker busy, few enough to hold nothing)
IN_FLIGHT = 4


def code_version():
    """``git describe --always --dirty`` of the source tree this package runs from, else the
    package version: what ``runs.csv`` records as the code that made each row."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=here, capture_output=True, text=True,
                             timeout=10)
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("contact_sim")
    except PackageNotFoundError:
        return "unknown"


# ---------------------------------------------------------------------------- executors
def inline_rows(study, todo, version):
    """Each run in this process, one after the other (``--workers 1``; ``run_study`` calls
    ``warm`` first)."""
    for _rid, cell, rep in todo:
        yield run_one(study, cell, rep, version)


_WORKER_STUDY = None


def _init_worker(study, forked):
    """A pool worker's start: keep the study, and load the kernels its runs use (``warm``: from
    numba's on-disk cache when spawned; already loaded when forked), so no run pays that."""
    global _WORKER_STUDY
    _WORKER_STUDY = study
    if not forked:
        warm(study)


def _pool_run(cell, rep, version):
    return run_one(_WORKER_STUDY, cell, rep, version)


def warm(study, seconds=1.0, most=16):
    """Run, without recording, up to ``seconds`` simulated seconds of one cell per distinct
    combination of the grid's non-numeric values (a *model* axis; at most ``most``): the kernels
    those runs use are compiled into numba's on-disk cache the first time (once, in the driver,
    before any worker starts or, with ``--workers 1``, before the first run) and loaded into this
    process, which forked workers inherit — so no worker compiles, and a run's ``cost`` does not
    include loading its kernels (except kernels first needed later than ``seconds`` into a run)."""
    seen = set()
    for cell in range(study.cells):
        key = tuple(label for _path, label, value in study.cell_params(cell)
                    if isinstance(value, bool) or not isinstance(value, numbers.Real))
        if key in seen:
            continue
        seen.add(key)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                scene, duration, drive = run_scene(study, cell, run_seed(study.seed, cell, 0)[0])
                world = load_scene(scene, base_dir=study.base_dir)
                motion = make_drive(drive, world, scene)
                dt = world.settings.dt
                for k in range(1, max(1, int(round(min(duration, seconds) / dt))) + 1):
                    if motion is not None:
                        motion(world, (k - 1) * dt)
                    world.step(dt)
            except Exception:   # a scene that cannot run is each run's error to record, not the driver's
                pass
        if len(seen) >= most:
            return


def start_method():
    """How the pool starts its workers: ``fork`` on Linux while this process runs a single thread
    (the workers are copies of the driver, the kernels it has loaded included: no import, no cache
    load, about 10 ms of start-up instead of seconds), else ``spawn`` (fresh interpreters that load
    the kernels from numba's on-disk cache). The engine's kernels are serial (no numba threading
    layer), so a fork from a single-threaded driver is safe; with other threads running (Ray
    initialised here, a progress bar's monitor) forking is not, and ``spawn`` is used."""
    import multiprocessing
    import threading

    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods() \
            and threading.active_count() == 1:
        return "fork"
    return "spawn"


def pool_rows(study, todo, version, workers):
    """Runs on ``workers`` local processes (``concurrent.futures``, started by ``start_method()``),
    at most ``IN_FLIGHT × workers`` submitted at a time; returns the generator of their rows. The
    driver steps the study's scene first, so its kernels are compiled once into numba's cache (and,
    forked, loaded) before any worker starts; the workers start here, before the caller opens files
    or starts a progress bar's thread."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    warm(study)
    method = start_method()
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context(method), initializer=_init_worker,
                               initargs=(study, method == "fork"))
    todo = iter(todo)
    pending = set()
    _fill(pool, pending, todo, version, workers)
    return _drain(pool, pending, todo, version, workers)


def _fill(pool, pending, todo, version, workers):
    while len(pending) < IN_FLIGHT * workers:
        nxt = next(todo, None)
        if nxt is None:
            return
        pending.add(pool.submit(_pool_run, nxt[1], nxt[2], version))


def _drain(pool, pending, todo, version, workers):
    from concurrent.futures import FIRST_COMPLETED, wait

    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            _fill(pool, pending, todo, version, workers)
            for f in done:
                yield f.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def ray_rows(study, todo, version, workers, address):
    """Runs as Ray tasks: on the cluster at ``address`` (``auto``: the one ``ray start --head``
    made, or ``RAY_ADDRESS``; ``ray://HOST:PORT``: through the Ray client), on a Ray instance
    already initialised in this process, or (``local``) on a new local one of ``workers`` CPUs;
    results streamed with ``ray.wait``, at most ``IN_FLIGHT ×`` the cluster's CPUs in flight."""
    try:
        import ray
    except ImportError:
        raise StudyError("--cluster", "Ray is not installed: pip install 'contact_sim[cluster]' "
                                      "(or pip install ray)") from None
    started = False
    if not ray.is_initialized():
        try:
            if address == "local":
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
            else:
                ray.init(address=address, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise StudyError(f"--cluster {address}", f"cannot connect to a Ray cluster ({exc}); start one with "
                                                     "`ray start --head`, or use --cluster local") from None
        started = True
    try:
        cpus = max(1, int(ray.cluster_resources().get("CPU", workers)))
        remote = ray.remote(num_cpus=1)(run_one)
        ref = ray.put(study)
        todo = iter(todo)
        pending = []
        while True:
            while len(pending) < IN_FLIGHT * cpus:
                nxt = next(todo, None)
                if nxt is None:
                    break
                pending.append(remote.remote(ref, nxt[1], nxt[2], version))
            if not pending:
                return
            done, pending = ray.wait(pending, num_returns=1)
            for r in done:
                yield ray.get(r)
    finally:
        if started:
            ray.shutdown()


# ---------------------------------------------------------------------------- rows on disk
def cell_text(value):
    """A value as ``runs.csv`` holds it: floats in their shortest exact form (``repr``), so
    reading them back gives the same bits; None as empty."""
    if value is None:
        return ""
    if isinstance(value, numbers.Integral):      # bool, int, numpy integers: as whole numbers
        return str(int(value))
    if isinstance(value, numbers.Real):
        v = float(value)
        return repr(v) if math.isfinite(v) else str(v)
    return str(value)


def done_runs(path, cols, fingerprint):
    """Ids of the runs already in ``path`` (a resume skips them). A last line cut short by an
    interruption is dropped; a file written by another study (other columns or fingerprint) is
    refused rather than mixed with."""
    if not os.path.exists(path):
        return set()
    with open(path, "rb+") as fh:   # drop a partial last line (a run killed while being written)
        data = fh.read()
        if data and not data.endswith(b"\n"):
            fh.truncate(data.rfind(b"\n") + 1)
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None:
            return set()
        if header != cols:
            raise StudyError(path, "holds the runs of a study with other columns; use another --out folder")
        ids, k, s = set(), cols.index("run_id"), cols.index("study")
        for row in reader:
            if len(row) != len(cols):
                continue
            if row[s] != fingerprint:
                raise StudyError(path, f"holds runs of another version of this study (fingerprint {row[s]}, "
                                       f"now {fingerprint}); use another --out folder")
            ids.add(row[k])
    return ids


def run_study(study, out, workers=None, cluster=None, progress=True, limit=None, stream=None):
    """Run ``study`` (a ``Study``, a study file, a shipped study's name or a dict), writing one row
    per run to ``out/runs.csv`` as each completes, then ``out/summary.csv`` and, where the study
    names one, ``out/plot.png``; returns ``(runs.csv path, summary rows)``.

    ``workers``: processes on this machine (default all cores; 1 runs in this process);
    ``cluster``: None (this machine), ``"local"`` (a new local Ray instance), ``"auto"`` (the
    running Ray cluster, or the Ray instance already initialised here) or ``"ray://HOST:PORT"``.
    ``limit`` runs only the first so many runs. Runs already in ``runs.csv`` are skipped (resume).
    ``stream``: where the summary table is printed (default stdout; False: not printed)."""
    study = load_study(study)
    workers = int(os.cpu_count() or 1) if workers is None else int(workers)
    if workers < 1:
        raise StudyError("--workers", f"must be >= 1, got {workers}")
    if cluster is not None and not (cluster in ("auto", "local") or str(cluster).startswith("ray://")):
        raise StudyError("--cluster", f"must be auto, local or ray://HOST:PORT, got {cluster!r}")
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "runs.csv")
    cols = columns(study)
    done = done_runs(path, cols, study.fingerprint)
    limit = len(study) if limit is None else max(0, min(int(limit), len(study)))

    def todo():     # the runs still to do, generated (a study of any length holds no list of them)
        return (r for r in itertools.islice(study.runs(), limit) if r[0] not in done)

    count = sum(1 for _ in todo())
    version = code_version()
    if cluster is not None:
        rows = ray_rows(study, todo(), version, workers, cluster)
    elif workers == 1 or count <= 1:
        if count:
            warm(study)     # as a pool's driver does: no run's cost includes loading its model's kernels
        rows = inline_rows(study, todo(), version)
    else:
        rows = pool_rows(study, todo(), version, min(workers, count))
    bar = None
    if progress and count:
        from tqdm import tqdm

        bar = tqdm(total=count, unit="run", file=sys.stderr, desc=study.name, dynamic_ncols=True)
    failed = 0
    fresh = not os.path.exists(path) or os.path.getsize(path) == 0
    with open(path, "a", newline="") as fh:
        w = csv.writer(fh)
        if fresh:
            w.writerow(cols)
            fh.flush()
        for row in rows:
            w.writerow([cell_text(row[c]) for c in cols])
            fh.flush()
            failed += bool(row["exception"])
            if bar is not None:
                bar.update(1)
                bar.set_postfix(failed=failed, refresh=False)
    if bar is not None:
        bar.close()
    summary = summarise(study, path, out, stream=sys.stdout if stream is None else stream)
    return path, summary

