#!/usr/bin/python3
"""Work-precision plot of a `subslip accuracy` study: maximum error against run time, log-log,
one curve per integrator, one PNG per case (DIR/accuracy_<case>.png).

    /usr/bin/python3 scripts/plot_accuracy.py DIR [-o OUT.png] [--case NAME] [--quiet]

Reads DIR/accuracy.csv and DIR/accuracy_reference.csv (written by subslip accuracy); needs
matplotlib (Debian: apt-get install python3-matplotlib). Failed runs (forward Euler beyond its
stability limit) have no error and are counted in the legend instead.
"""
import argparse
import csv
import math
import os
import re
import sys

STYLE = {  # integrator -> (label, marker, colour)
    "forward_euler": ("forward Euler (fixed step)", "s", "tab:red"),
    "implicit": ("implicit (fixed step)", "o", "tab:blue"),
    "implicit_adaptive": ("implicit (adaptive)", "D", "tab:green"),
    "extrapolated_2": ("extrapolated, order 2", "v", "tab:orange"),
    "extrapolated_3": ("extrapolated, order 3", "<", "tab:brown"),
    "extrapolated_4": ("extrapolated, order 4", ">", "tab:olive"),
    "cvode": ("CVODE (BDF)", "^", "tab:purple"),
}


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def file_stem(case):
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", case)


def label_of(row):
    if row["setting_kind"].startswith("increment factor"):
        return "x%g" % number(row["setting"])
    return "%.0e" % number(row["setting"])


def plot_case(plt, case, rows, reference, out):
    fig, ax = plt.subplots(figsize=(5.6, 4.0), dpi=90)
    for integrator, (label, marker, colour) in STYLE.items():
        mine = [r for r in rows if r["integrator"] == integrator]
        if not mine:
            continue
        good = [r for r in mine if r["status"] == "ok" and number(r["max_error"]) > 0]
        failed = len([r for r in mine if r["status"] == "failed"])
        stopped = len([r for r in mine if r["status"] == "stopped"])
        notes = []
        if failed:
            notes.append("%d failed" % failed)
        if stopped:
            notes.append("%d over time budget" % stopped)
        if not good:
            notes.append("no result")
        if notes:
            label += " (%s)" % ", ".join(notes)
        if not good:
            ax.plot([], [], marker=marker, color=colour, label=label)
            continue
        t = [number(r["median_time_s"]) for r in good]
        e = [number(r["max_error"]) for r in good]
        ax.plot(t, e, marker=marker, color=colour, label=label, lw=1.2, ms=4)
        for r, x, y in zip(good, t, e):
            ax.annotate(label_of(r), (x, y), fontsize=6, color=colour,
                        xytext=(3, 2), textcoords="offset points")
    # Runs compared with a reference at their own times carry its resolution (reference_error):
    # the largest of those is the floor; otherwise the shared reference's own error: its
    # difference from CVODE when that ran (an independent integration), else its
    # self-convergence estimate.
    own = [number(r.get("reference_error")) for r in rows if r["status"] == "ok"]
    own = [x for x in own if x > 0]
    if own:
        ax.axhline(max(own), color="grey", ls=":", lw=1)
        ax.annotate("references at the runs' times (largest error)", (0.01, max(own)),
                    xycoords=("axes fraction", "data"), ha="left", va="bottom", fontsize=6,
                    color="grey")
    elif reference:
        cvode = number(reference.get("cvode_difference"))
        level = cvode if cvode > 0 else number(reference.get("self_convergence"))
        if level > 0:
            ax.axhline(level, color="grey", ls=":", lw=1)
            ax.annotate("reference vs CVODE" if cvode > 0 else "reference self-convergence",
                        (0.01, level), xycoords=("axes fraction", "data"), ha="left",
                        va="bottom", fontsize=6, color="grey")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median run time [s]")
    quantity = "value"
    if reference:
        quantity = reference.get("measured") or reference.get("quantity") or "value"
    ax.set_ylabel("max error of %s / scale" % quantity, fontsize=7 if len(quantity) > 20 else None)
    title = reference.get("title", "") if reference else ""
    ax.set_title(("%s\ncase %s" % (title, case)) if title else "case %s" % case, fontsize=8)
    ax.grid(True, which="major", lw=0.4, alpha=0.5)
    ax.legend(fontsize=6.5, loc="lower right")
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dir", help="the study directory (subslip accuracy -o DIR)")
    parser.add_argument("-o", "--output", help="PNG file (only with one case or --case)")
    parser.add_argument("--case", help="plot only this case")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args()
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.stderr.write(
            "plot_accuracy.py: matplotlib is missing (Debian: apt-get install python3-matplotlib); "
            "the tables are written; then run: /usr/bin/python3 %s %s\n" % (sys.argv[0], args.dir))
        return 3
    rows = read_csv(os.path.join(args.dir, "accuracy.csv"))
    references = {r["case"]: r for r in read_csv(os.path.join(args.dir, "accuracy_reference.csv"))}
    cases = [c for c in references if args.case in (None, c)]
    if not cases:
        sys.stderr.write("plot_accuracy.py: no case %r in %s\n" % (args.case, args.dir))
        return 2
    if args.output and len(cases) > 1:
        sys.stderr.write("plot_accuracy.py: -o needs a single case (use --case)\n")
        return 2
    for case in cases:
        out = args.output or os.path.join(args.dir, "accuracy_%s.png" % file_stem(case))
        plot_case(plt, case, [r for r in rows if r["case"] == case], references.get(case), out)
        if not args.quiet:
            print("plot: %s" % out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
