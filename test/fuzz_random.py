"""The long property profile with fresh random draws (``make fuzz-random N=<examples per property>``).

Runs each property of ``test_properties.py`` (``test_fuzz[<property>]``) in its own pytest process,
``JOBS`` at a time (default: the machine's cores), with hypothesis drawing new examples from one
printed seed. Every failing example is saved as a case (YAML: the property, the scene mapping, the
call sequence, what failed) in the folder ``--save`` (default ``fuzz-found/``, not tracked) and the
run goes on, so one run reports every failure it meets. A saved case replays with
``pytest test/test_properties.py -k saved_case`` once moved into ``test/cases/`` (CI checks every
case there), or by hand: ``test_properties.run_case(test_properties.load_case(path))``.

Usage: ``python test/fuzz_random.py --examples 2000 [--seed S] [--jobs J] [--only name ...]``.
Same seed and examples: the same draws (CI keeps the derandomized profile, ``make fuzz``).
"""
import argparse
import os
import secrets
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)


def run_property(name, examples, seed, save):
    """One property's long profile in a pytest process: ``(name, seconds, exit code, saved files)``."""
    env = dict(os.environ, CONTACT_SIM_FUZZ_RANDOM="1", CONTACT_SIM_FUZZ_EXAMPLES=str(examples),
               CONTACT_SIM_FUZZ_SAVE=save)
    before = set(os.listdir(save)) if os.path.isdir(save) else set()
    t0 = time.perf_counter()
    # no per-test timeout (pytest.ini's 300 s): one test is a whole property's examples
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "fuzz", "--timeout=0",
                           f"--hypothesis-seed={seed}", f"test/test_properties.py::test_fuzz[{name}]"],
                          cwd=REPO, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    after = set(os.listdir(save)) if os.path.isdir(save) else set()
    saved = sorted(f for f in after - before if f.startswith(name + "_") and f.endswith(".yaml"))
    if proc.returncode and not saved:   # a failure that saved nothing (a crash, a collection error)
        sys.stderr.write(proc.stdout[-4000:] + proc.stderr[-4000:])
    return name, seconds, proc.returncode, saved


def main(argv=None):
    from test_properties import PROPERTIES

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--examples", type=int, required=True, help="examples per property")
    ap.add_argument("--seed", type=int, default=None, help="hypothesis seed (default: a fresh one, printed)")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="properties run at once")
    ap.add_argument("--save", default=os.path.join(REPO, "fuzz-found"), help="folder the failing cases go to")
    ap.add_argument("--only", nargs="*", choices=list(PROPERTIES), help="these properties only")
    args = ap.parse_args(argv)
    seed = secrets.randbelow(2 ** 32) if args.seed is None else args.seed
    names = args.only or list(PROPERTIES)
    print(f"fuzz-random: seed {seed}, {args.examples} examples per property, {len(names)} properties, "
          f"{args.jobs} at a time; failing cases go to {args.save}", flush=True)
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(lambda n: run_property(n, args.examples, seed, args.save), names))
    print(f"\n{'property':<26} {'examples':>9} {'seconds':>9} {'failing cases':>14}")
    failed = False
    for name, seconds, code, saved in results:
        print(f"{name:<26} {args.examples:>9} {seconds:>9.0f} {len(saved) if saved or not code else 'error':>14}")
        failed |= bool(code)
    print(f"total {time.perf_counter() - t0:.0f} s (seed {seed})")
    for name, _, _, saved in results:
        for f in saved:
            print("  saved", os.path.join(args.save, f))
    if failed:
        print("replay: move a case into test/cases/ and run `pytest test/test_properties.py -k saved_case`")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
