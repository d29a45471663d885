"""Benchmarks and convergence studies (scripts: python -m workflow.bench.<name>)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def run_to(scene: str, product: str, folder: Path) -> Path:
    """``bladewear run scene`` up to ``product`` (cached like any run) into ``folder``; returns it."""
    subprocess.run([str(Path(sys.executable).parent / "bladewear"), "run", scene, "--set",
                    f'run.outputs=["{product}"]', "--out", str(folder), "--quiet"], check=True)
    return Path(folder)


def scene_disk(scene_name: str, sets, out: Path):
    """(scene, substructures) of a cyclic scene's whole disk: the sector bundle built through the
    pipeline into ``out/<scene>-bundle`` (cached like any run), split into its blade and
    disk-per-ND substructures (:func:`reduction.mistuned.substructures`) with the scene's
    ``[mistuning]`` modes and ``[cyclic] engine_order``; ``sets`` the scene overrides."""
    from reduction.bundle import read_bundle
    from reduction.mistuned import substructures
    from workflow.scene import load_scene
    from workflow.stages.assembly import bundle_folder

    run_dir = Path(out) / f"{scene_name}-bundle"
    run_to(scene_name, "bundle", run_dir)
    scene = load_scene(scene_name, sets)
    mt, eo = scene["mistuning"], int(scene["cyclic"].engine_order)
    return scene, substructures(read_bundle(bundle_folder(run_dir / "assembly")), eo, mt.blade_modes, mt.disk_modes)
