#!/usr/bin/env python3
"""Does a tolerance mean what it says? Every case of the given scenes at a ladder of tolerances
with the default order (a tolerance and no `order`): whether it runs to the end, and its largest
error on the path against a tight reference, as a multiple of the tolerance.

    bench/tolerance_sweep.py SUBSLIP SCENE.yaml ... [--tolerances 1e-3 ... 1e-8]
        [--reference-tolerance 1e-11] [--order K] [--compare-order-1] [--coarsest] [--workdir DIR]
        [--max-cases N] [--crystal-measure state|stress|resolved] [--per-case]
        [--case-seconds S] [--max-run-seconds S]

SUBSLIP is the built CLI (build/src/subslip). Contact scenes: each case (one per element of the
scene's sweep) runs with `integrator: {method: implicit, tolerance: T}` (plus `order: K` with
--order), and the reference (order 2 at --reference-tolerance) runs with its steps ending on
exactly that run's output times (`output.at`): the error is |f_t/f_n - reference| / mu_s, on
the tangential traction vector (what the estimate controls: a 2-D turn or a reversal errs in the
traction's direction, which its magnitude |f_t|/f_n hides), at every step the run takes,
compared at the same times without interpolation (a reference
interpolated between its own steps is wrong by more than the runs where both take long steps
towards a steady state). Steps whose time repeats the one before (a step below the absolute
time's resolution) are left out of the comparison, and so are steps shorter than 64 ulp of
their time (counted in the cell as "unresolved"), and a difference up to the traction ratio's slope
times what the absolute time resolves there (the two times' distance plus 2 ulp) is not counted:
it is the same state compared at times the output cannot tell apart. Crystal scenes: `subslip accuracy` with
`--reference-at-run-times` (docs/accuracy.md), integrator `extrapolated_2`, measured by default on
every grain's resolved shear over its yield scale (`--crystal-measure resolved`: the tolerance's own
unit, the CRSS or a compressed pressure-sensitive plane's yield traction mu f_n).

With --compare-order-1 each contact case also runs backward Euler's own estimate (`order: 1`) at
the same tolerances, and the summary gives, for each of its points, the run time of the cheapest
default-order point at least as accurate (work-precision at equal error; wall time of one run,
so compare only large ratios on a shared machine).

A crystal scene is one study of all its cases; with --per-case each case is its own study (its
own scene file in the work directory, the orientation file's path made absolute), so that a case
whose references take long stops alone (--case-seconds) and the others are still compared.
--max-cases then applies to crystal scenes too.

With --coarsest each case also runs at a tolerance of 1, its coarsest path (the fewest steps its
step control takes; a contact scene's tolerance must be below 1, so 0.999 there; a crystal's in a
study of its own with the free stresses solved to 1e-10 of the stress scale, the fixed-increment
default, so that the path's error is its steps' and not the loose inner solve a tolerance of 1
ties), and a run below 0.1 times its tolerance counts as "coarsest path as
accurate" where that path's error is itself below a tenth of the run's tolerance (no tolerance
can make the run less accurate than asked), else as "more accurate than asked".

Prints one row per case, a cell per tolerance ("error/tolerance (steps)", or the failure), then a
summary: runs that reached the end, and how many ended within 0.1 ... 10 times the tolerance,
below 0.1 (more accurate than asked) or above 10. Benchmarks are not tests: nothing is asserted.
Run it with `nice` on a shared machine.
"""
import argparse
import bisect
import copy
import csv
import itertools
import math
import os
import re
import subprocess
import sys
import tempfile
import time

import yaml


class SceneLoader(yaml.SafeLoader):
    """YAML 1.2 numbers: 1e-4 is a float (YAML 1.1 reads it as a string)."""


SceneLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^[-+]?\.(inf|Inf|INF)$|^\.(nan|NaN|NAN)$"),
    list("-+0123456789."))


def load_scene(path):
    with open(path) as f:
        return yaml.load(f, Loader=SceneLoader)


def cases_of(scene):
    """(name, single-case scene) for every element of the scene's sweep."""
    sweep = scene.get("sweep")
    base = {k: v for k, v in scene.items() if k != "sweep"}
    if not sweep:
        return [("base", base)]
    keys = list(sweep.keys())
    out = []
    for values in itertools.product(*(sweep[k] for k in keys)):
        s = copy.deepcopy(base)
        s["sweep"] = {k: [v] for k, v in zip(keys, values)}
        name = ",".join(f"{k.split('.')[-1]}={flow(v)}" for k, v in zip(keys, values))
        out.append((name, s))
    return out


def studied_cases(scene, args):
    """The scene's cases a sweep studies: all, or the first --max-cases."""
    cases = cases_of(scene)
    return cases[:args.max_cases] if args.max_cases else cases


def flow(value):
    """A swept value as YAML flow text (a mapping or a list inline), as case names show it."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {flow(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(flow(v) for v in value) + "]"
    return str(value)


def with_integrator(scene, tolerance, order, fields, at_times=None):
    s = copy.deepcopy(scene)
    integrator = {k: v for k, v in (s.get("integrator") or {}).items()
                  if k not in ("order", "tolerance", "method")}
    integrator.update({"method": "implicit", "tolerance": float(tolerance)})
    if order:
        integrator["order"] = int(order)
    s["integrator"] = integrator
    s["output"] = {"fields": fields}
    if at_times is not None:
        s["output"]["at"] = {"time": at_times}
    return s


RUN_SECONDS = 120.0  # --max-run-seconds


def run(subslip, scene, workdir, tag):
    path = os.path.join(workdir, tag + ".yaml")
    with open(path, "w") as f:
        yaml.safe_dump(scene, f, sort_keys=False)
    h5 = os.path.join(workdir, tag + ".h5")
    start = time.perf_counter()
    try:
        done = subprocess.run([subslip, "run", path, "-o", h5, "-f", "-q", "-j", "1"],
                              capture_output=True, text=True, timeout=RUN_SECONDS)
    except subprocess.TimeoutExpired:
        return None, RUN_SECONDS, f"stopped after {RUN_SECONDS:g} s"
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        return None, seconds, (done.stderr.strip().splitlines() or ["failed"])[-1]
    out = os.path.join(workdir, tag + "_csv")
    subprocess.run([subslip, "post", h5, "--csv", out, "-f", "-q", "--dataset", "traction"],
                   check=True, capture_output=True)
    traction_csv = next(f for f in os.listdir(out) if f.endswith("_traction.csv"))  # one case
    with open(os.path.join(out, traction_csv), newline="") as f:
        rows = list(csv.reader(f))[1:]  # step, time, f_x, f_y, f_n
    summary = subprocess.run([subslip, "post", h5], capture_output=True, text=True).stdout
    steps = re.search(r"^\s*increments\s*=\s*(\d+)", summary, re.M)
    mu_s = re.search(r"^\s*mu_s\s*=\s*([0-9.eE+-]+)", summary, re.M)
    os.remove(h5)
    return {"time": [float(r[1]) for r in rows], "traction": [traction_ratio(r) for r in rows],
            "steps": int(steps.group(1)) if steps else -1,
            "mu_s": float(mu_s.group(1)) if mu_s else math.nan}, seconds, None


def traction_ratio(row):
    """The tangential traction over f_n, (f_x, f_y) / f_n, of a traction CSV row; zero where the
    contact is open (f_n <= 0: no traction)."""
    fx, fy, fn = float(row[2]), float(row[3]), float(row[4])
    return (fx / fn, fy / fn) if fn > 0.0 else (0.0, 0.0)


def distance(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1])


def own_times(got):
    """The run's output times after the initial state, without repeats, and the tangential
    traction over f_n (a 2-vector) at each."""
    times, ratios, previous = [], [], -math.inf
    for t, r in zip(got["time"][1:], got["traction"][1:]):
        if t > previous:
            times.append(t)
            ratios.append(r)
        previous = t
    return times, ratios


# A contact scene's output must include `ratio`; the comparison reads `traction`.
CONTACT_FIELDS = ["time", "ratio", "traction"]


def contact_points(subslip, scene, runs, reference_tolerance, workdir, tag):
    """For each (tolerance, order) of `runs`: (max error / tolerance, steps, wall seconds, max
    error) or a failure message. One reference run ends a step on every time of every run."""
    out, got_all = {}, {}
    for tolerance, order in runs:
        got, seconds, why = run(subslip, with_integrator(scene, tolerance, order, CONTACT_FIELDS),
                                workdir, f"{tag}_{tolerance}_{order}")
        if got is None:
            out[(tolerance, order)] = why
        else:
            got_all[(tolerance, order)] = (got, seconds)
    if not got_all:
        return out
    # Every time of every run, those within 16 eps merged (the parser takes points that close
    # to a segment's end as that end, and refuses two equal points); a time compared with the
    # reference's at a merged neighbour is compared with the slope's allowance below.
    union = []
    for t in sorted(set(t for got, _ in got_all.values() for t in own_times(got)[0])):
        if not union or t > union[-1] * (1.0 + 16 * sys.float_info.epsilon):
            union.append(t)
    reference = with_integrator(scene, reference_tolerance, 2, CONTACT_FIELDS, union)
    ref, _, why = run(subslip, reference, workdir, tag + "_ref")
    for key, (got, seconds) in got_all.items():
        if ref is None:
            out[key] = "reference: " + why
            continue
        times, ratios = own_times(got)
        errors, unresolved = [], 0
        for k, (t, r) in enumerate(zip(times, ratios)):
            # A step shorter than 64 ulp of its absolute time (the first steps of an impact
            # 609 min into a history: 1e-13 min) is not resolved by the time it is output at:
            # no comparison at absolute times can tell its states apart.
            gaps = [abs(times[i] - t) for i in (k - 1, k + 1) if 0 <= i < len(times)]
            if gaps and min(gaps) < 64 * sys.float_info.epsilon * abs(t):
                unresolved += 1
                continue
            # The reference's step ending on t, or on a stop within round-off of it (the driver
            # ends a step on a stop within 8 eps of the time: two runs' times that close are one).
            j = bisect.bisect_left(ref["time"], t)
            near = [i for i in (j - 1, j) if 0 <= i < len(ref["time"]) and
                    abs(ref["time"][i] - t) <= 64 * sys.float_info.epsilon * abs(t)]
            if near:
                nearest = min(near, key=lambda i: abs(ref["time"][i] - t))
                # What absolute times cannot resolve: a run's step ends at (start of its
                # segment) + (time into it), rounded to an ulp of the absolute time, and the
                # reference's stop is that rounded time taken back into the segment, another
                # ulp. On a ramp of slope s the same state is then compared at times up to
                # |t - t_ref| + 2 ulp(t) apart, a difference of s times that which is no error
                # of either run (the first steps of a re-slide 61 min into a history: 1e-6 ...
                # 1e-4 of mu_s). The slope is the run's own, the steeper of its two chords.
                slope = 0.0
                for a, b in ((k - 1, k), (k, k + 1)):
                    if 0 <= a and b < len(times) and times[b] > times[a]:
                        chord = distance(ratios[b], ratios[a]) / (times[b] - times[a])
                        slope = max(slope, chord)
                apart = abs(ref["time"][nearest] - t) + 2 * sys.float_info.epsilon * abs(t)
                raw = distance(r, ref["traction"][nearest])
                errors.append(max(0.0, raw - slope * apart))
        # A few times the reference cannot end a step on (round-off of a segment's start time,
        # or two stops within round-off merged into one that ends elsewhere) are left out.
        if len(errors) < 0.99 * (len(times) - unresolved):
            out[key] = f"reference has {len(errors)} of the {len(times) - unresolved} times"
            continue
        error = max(errors) / got["mu_s"]
        out[key] = (error / float(key[0]), got["steps"], seconds, error, unresolved)
    return out


def crystal_study(subslip, path, out, args, tolerances):
    """One `subslip accuracy` study of the crystal scene at `path` into `out` at `tolerances`: its
    rows, or None and why."""
    cmd = [subslip, "accuracy", path, "-o", out, "-f", "-q", "--no-plot",
           "--integrators", "extrapolated_2", "--extrapolated", *tolerances,
           "--reference-tolerance", args.reference_tolerance, "--reference-order", "2",
           "--reference-at-run-times", "--repeat", "1", "--measure", args.crystal_measure,
           "--max-run-seconds", str(args.max_run_seconds)]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True,
                              timeout=args.case_seconds or None)
    except subprocess.TimeoutExpired:
        return None, f"study stopped after {args.case_seconds:g} s"
    csv_path = os.path.join(out, "accuracy.csv")
    if not os.path.exists(csv_path):
        return None, (done.stderr.strip().splitlines() or ["no output"])[-1]
    with open(csv_path, newline="") as f:
        return list(csv.DictReader(f)), None


# The free stresses' tolerance of a crystal's coarsest path (--coarsest), relative to the stress
# scale: the scene default of fixed increments. A run at tolerance T brings its free stresses
# within T/100 of the smallest CRSS (docs/integrators.md), so at T = 1 a path solved as the run
# solves it errs by up to a hundredth of the CRSS wherever lateral stresses are held (1.8e-3 on
# the Cu [001] crystal's sigma_33 at G/tau0 = 100, whose steps alone are 7.7e-6 off): that is the
# inner solve, not the path. Solved this tightly, the coarsest path is what its steps give, and
# no run, which takes at least its steps and solves them to at most T/100, is less accurate.
COARSEST_STRESS_TOLERANCE = 1.0e-10


def write_scene(scene, here, path):
    """Writes `scene` (read from a file in directory `here`) to `path`, its orientation file's
    path made absolute."""
    orientations = scene.get("orientations") or {}
    if "file" in orientations:
        orientations["file"] = os.path.join(here, orientations["file"])
    with open(path, "w") as f:
        yaml.safe_dump(scene, f, sort_keys=False)


def crystal_scene_rows(subslip, scene, here, workdir, name, args):
    """The rows of one crystal study of `scene` (the table's tolerances) and, with --coarsest,
    of its coarsest path solved tightly (COARSEST_STRESS_TOLERANCE), or None and why."""
    path = os.path.join(workdir, f"{name}.yaml")
    write_scene(copy.deepcopy(scene), here, path)
    rows, why = crystal_study(subslip, path, os.path.join(workdir, name), args, args.tolerances)
    if rows is None or not args.coarsest:
        return rows, why
    tight = copy.deepcopy(scene)
    integrator = tight.setdefault("integrator", {})
    integrator.setdefault("stress_tolerance", COARSEST_STRESS_TOLERANCE)
    tight_path = os.path.join(workdir, f"{name}_coarsest.yaml")
    write_scene(tight, here, tight_path)
    coarse, why = crystal_study(subslip, tight_path, os.path.join(workdir, f"{name}_coarsest"),
                                args, [COARSEST["crystal"]])
    return rows + (coarse or []), None


def crystal_rows(subslip, path, args, workdir):
    """The study's rows of every case of a crystal scene (one study, or with --per-case one per
    case: a case whose references take long then stops alone), and the cases that gave none."""
    stem = os.path.splitext(os.path.basename(path))[0]
    scene = load_scene(path)
    here = os.path.dirname(os.path.abspath(path))
    if not args.per_case:
        rows, why = crystal_scene_rows(subslip, scene, here, workdir, stem, args)
        return (rows or []), ([] if rows is not None else [(None, why)])
    rows, missing = [], []
    for k, (case, single) in enumerate(studied_cases(scene, args)):
        got, why = crystal_scene_rows(subslip, single, here, workdir, f"{stem}_{k}", args)
        if got is None:
            missing.append((case, why))
        else:
            rows += got
    return rows, missing


# The tolerance of a case's coarsest path (--coarsest): the loosest a scene takes.
COARSEST = {"crystal": "1", "contact": "0.999"}


def studied_tolerances(args, kind):
    """The tolerances each case runs at: the table's, and with --coarsest the coarsest path's."""
    extra = [COARSEST[kind]] if args.coarsest and COARSEST[kind] not in args.tolerances else []
    return list(args.tolerances) + extra


def band(ratio, tolerance, coarsest_error):
    """Where a run's max error over its tolerance falls; below 0.1 split by the coarsest path's
    error where it was run (None: not run)."""
    if ratio < 0.1:
        if coarsest_error is None:
            return "below 0.1"
        if coarsest_error < 0.1 * tolerance:
            return "below 0.1, coarsest path as accurate"
        return "below 0.1, more accurate than asked"
    if ratio <= 10.0:
        return "0.1 ... 10"
    return "above 10"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("subslip")
    p.add_argument("scenes", nargs="+")
    p.add_argument("--tolerances", nargs="+",
                   default=["1e-3", "1e-4", "1e-5", "1e-6", "1e-7", "1e-8"])
    p.add_argument("--reference-tolerance", default="1e-11")
    p.add_argument("--order", type=int, default=0, help="0: the scene default (none given)")
    p.add_argument("--compare-order-1", action="store_true")
    p.add_argument("--coarsest", action="store_true",
                   help="also run each case at a tolerance of 1 (its coarsest path)")
    p.add_argument("--workdir", default=None)
    p.add_argument("--max-cases", type=int, default=0, help="per scene, 0: all")
    p.add_argument("--crystal-measure", choices=["state", "stress", "resolved"], default="resolved")
    p.add_argument("--max-run-seconds", type=float, default=120.0)
    p.add_argument("--per-case", action="store_true",
                   help="crystal scenes: one study per case (each with its own references)")
    p.add_argument("--case-seconds", type=float, default=0.0,
                   help="crystal: stop a study after this long, 0: no limit")
    args = p.parse_args()
    global RUN_SECONDS
    RUN_SECONDS = args.max_run_seconds
    workdir = args.workdir or tempfile.mkdtemp(prefix="tolerance_sweep_")
    os.makedirs(workdir, exist_ok=True)

    print(f"order {args.order or 'default'}; reference: order 2 at {args.reference_tolerance} at "
          "each run's own times; cell: max error over the path / tolerance (steps)\n")
    print("| scene | case | " + " | ".join(args.tolerances) + " |")
    print("|---|---|" + "---|" * len(args.tolerances), flush=True)
    runs = ended = 0
    bands, failures, equal_error, below = {}, [], [], []

    def count(name, case, tol, ratio, coarsest_error):
        kind = band(ratio, float(tol), coarsest_error)
        bands[kind] = bands.get(kind, 0) + 1
        if kind == "below 0.1, more accurate than asked":
            below.append(f"{name} {case} at {tol}: {ratio:.2g} (coarsest path {coarsest_error:.2g})")

    for path in args.scenes:
        name = os.path.basename(path)
        scene = load_scene(path)
        if scene.get("scene") == "crystal":
            rows, missing = crystal_rows(args.subslip, path, args, workdir)
            for case, why in missing:
                if case is None:  # (the whole scene's study)
                    failures.append(f"{name}: {why}")
                    continue
                runs += len(args.tolerances)
                failures.append(f"{name} {case}: {why}")
            for case in dict.fromkeys(r["case"] for r in rows):
                cells = []
                coarse = next((x for x in rows if x["case"] == case and x["status"] == "ok" and
                               float(x["setting"]) == float(COARSEST["crystal"])), None) if args.coarsest else None
                coarsest_error = float(coarse["max_error"]) if coarse else None
                for tol in args.tolerances:
                    r = next((x for x in rows if x["case"] == case and
                              float(x["setting"]) == float(tol)), None)
                    runs += 1
                    if r is None or r["status"] != "ok":
                        why = "not run" if r is None else r["status"] + " " + r["failure"]
                        cells.append("**" + why.split()[0] + "**")
                        failures.append(f"{name} {case} at {tol}: {why[:300]}")
                        continue
                    ended += 1
                    ratio = float(r["error_to_tolerance"])
                    count(name, case, tol, ratio, coarsest_error)
                    cells.append(f"{ratio:.2g} ({r['steps']})")
                print(f"| {name} | {case} | " + " | ".join(cells) + " |", flush=True)
            continue
        for k, (case, single) in enumerate(studied_cases(scene, args)):
            wanted = [(tol, args.order) for tol in studied_tolerances(args, "contact")]
            if args.compare_order_1:
                wanted += [(tol, 1) for tol in args.tolerances]
            results = contact_points(args.subslip, single, wanted, args.reference_tolerance,
                                     workdir, f"{os.path.splitext(name)[0]}_{k}")
            cells, points = [], {}
            coarse = results.get((COARSEST["contact"], args.order)) if args.coarsest else None
            coarsest_error = coarse[3] if coarse is not None and not isinstance(coarse, str) else None
            for tol in args.tolerances:
                runs += 1
                got = results[(tol, args.order)]
                if isinstance(got, str):
                    cells.append("**reference**" if got.startswith("reference") else "**failed**")
                    failures.append(f"{name} {case} at {tol}: {got[:300]}")
                    continue
                ended += 1
                ratio, steps, seconds, error, unresolved = got
                points[tol] = (error, seconds)
                count(name, case, tol, ratio, coarsest_error)
                cells.append(f"{ratio:.2g} ({steps}{f', {unresolved} unresolved' if unresolved else ''})")
            print(f"| {name} | {case} | " + " | ".join(cells) + " |", flush=True)
            if args.compare_order_1:
                for tol in args.tolerances:
                    got = results[(tol, 1)]
                    if isinstance(got, str):
                        equal_error.append((name, case, tol, math.nan, math.nan, math.nan))
                        continue
                    _, _, seconds, error, _ = got
                    better = [s for e, s in points.values() if e <= error]
                    equal_error.append((name, case, tol, error, seconds,
                                        min(better) if better else math.nan))
    print(f"\n{ended} of {runs} runs reached the end; max error over the tolerance: " +
          ", ".join(f"{k}: {v}" for k, v in sorted(bands.items())))
    for f in failures:
        print(f"  not ended: {f}")
    for b in below:
        print(f"  more accurate than asked: {b}")
    if equal_error:
        print("\nwork-precision: each order-1 point against the cheapest default-order point at "
              "least as accurate (wall seconds of one run, with the process start)")
        print("| scene | case | order-1 tolerance | order-1 error | order 1 [s] | default [s] |")
        print("|---|---|---|---|---|---|")
        for name, case, tol, e1, t1, t2 in equal_error:
            print(f"| {name} | {case} | {tol} | {e1:.2g} | {t1:.3g} | {t2:.3g} |")
    print(f"\n(runs in {workdir})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
