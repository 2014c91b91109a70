#!/usr/bin/python3
"""The figure of a fit's report (fit: contact or fit: crystal): data against fit for every curve,
and the residuals.

    subslip fit FIT.yaml --output fit.json
    /usr/bin/python3 scripts/fit_report.py fit.json fit.png     # or fit.pdf

The drawing is subslip.fit_figure (python/subslip/calibration.py); this script reads the JSON
report `subslip fit --output` writes. Needs matplotlib (python3-matplotlib).
"""

import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))

from subslip.calibration import fit_figure  # noqa: E402


def main(argv):
    if len(argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        with open(argv[1], encoding="utf-8") as f:
            report = json.load(f)
    except (OSError, ValueError) as e:
        print(f"fit_report.py: {argv[1]}: {e}", file=sys.stderr)
        return 2
    fit_figure(report, argv[2])
    print(argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
