#!/usr/bin/env python3
"""Runs the scene README.md teaches ("A first scene") exactly as written, and its commands.

The README's first YAML block after the heading "## A first scene" is written to a file and run
with the subslip binary (SUBSLIP_BINARY); then `subslip post` on the result. Checks what the
README says the scene does: it runs to the end, the file is finished with one row per increment
plus the start, the strain reaches the stated 2 %, the lateral stresses the scene prescribes as
0 are 0 to the mixed control's tolerance, and the per-grain slips it asks for are stored.
Usage: check_readme_scene.py README.md
"""
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np


def first_scene(readme_text):
    section = readme_text.split("## A first scene", 1)[1]
    match = re.search(r"```yaml\n(.*?)```", section, re.S)
    if not match:
        sys.exit("README.md: no ```yaml block after '## A first scene'")
    return match.group(1)


def main():
    binary = os.environ["SUBSLIP_BINARY"]
    scene_text = first_scene(open(sys.argv[1], encoding="utf-8").read())
    increments = int(re.search(r"increments:\s*(\d+)", scene_text).group(1))
    strain = float(re.search(r"strain:\s*([0-9.eE+-]+)", scene_text).group(1))
    with tempfile.TemporaryDirectory() as d:
        scene = os.path.join(d, "my_first.yaml")
        result = os.path.join(d, "first.h5")
        open(scene, "w", encoding="utf-8").write(scene_text)
        subprocess.run([binary, "run", scene, "-o", result], check=True)
        subprocess.run([binary, "post", result], check=True, stdout=subprocess.DEVNULL)
        with h5py.File(result) as f:
            assert f.attrs["completed"] == 1 and f.attrs["finished"] == 1
            case = f["cases/base"]
            stress = case["macro/stress"][()]
            assert stress.shape == (increments + 1, 3, 3), stress.shape
            # The segment ends where the integral of D_33 reaches the strain; the stored strain
            # is ln V, which the Cayley map of F carries to within (L dt)^2/12 of it, relative
            # (docs/scenes.md, "Output at chosen points").
            l_dt = strain / increments
            final_strain = case["macro/strain"][-1, 2, 2]
            assert abs(final_strain - strain) <= 2 * l_dt**2 / 12 * strain, final_strain
            lateral = np.abs(stress[:, [0, 1], [0, 1]]).max()
            assert lateral <= 1e-6 * np.abs(stress[:, 2, 2]).max(), lateral
            assert case["grains/slip"].shape[0] == increments + 1
    print("README's first scene: ran, %d rows, strain %.3g, lateral stress 0" % (increments + 1, strain))


if __name__ == "__main__":
    main()
