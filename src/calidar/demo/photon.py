"""Demo step for ``calidar demo``: simulate a CCR pass and calibrate it (a few seconds)."""

from __future__ import annotations

from pathlib import Path

from calidar.photon.ccr import SearchSettings, SystemParameters


def photon_step(report, out_dir: Path, seed: int, progress=None) -> None:
    """Simulate a pass over 8 CCRs into ``out_dir/photon``, calibrate, add the report section."""
    from calidar.outputs import prepare_out_dir
    from calidar.pipelines.ccr import run_ccr
    from calidar.sim.photons import PhotonSimConfig, simulate_pass, write_pass

    sim_dir = prepare_out_dir(Path(out_dir) / "photon" / "sim", force=True)
    paths = write_pass(simulate_pass(PhotonSimConfig(seed=seed, n_ccr=8, n_unlit=1)), sim_dir)
    run_ccr([paths["atl03"]], "gt1l", paths["ccr"], Path(out_dir) / "photon" / "ccr", system=SystemParameters(),
            settings=SearchSettings(), truth_path=paths["truth"], force=True, report=report)
