"""Demo step for ``calidar demo``: simulate a CCR pass and calibrate it (a few seconds)."""

from __future__ import annotations

from pathlib import Path

from calidar.pipelines import Progress, no_progress


def photon_step(report, out_dir: Path, seed: int, progress: Progress = no_progress) -> None:
    """Simulate a pass over 8 CCRs into ``out_dir/photon/sim``, calibrate it into ``photon/ccr``,
    add the report section and its verdict."""
    from calidar.outputs import prepare_out_dir
    from calidar.photon.search import SearchSettings
    from calidar.pipelines.ccr import run_ccr, simulate_photons
    from calidar.pipelines.ccr_config import CCRConfig
    from calidar.sim.photons import PhotonSimConfig

    sim_dir = prepare_out_dir(Path(out_dir) / "photon" / "sim", force=True)
    paths = simulate_photons(PhotonSimConfig(seed=seed, n_ccr=8, n_unlit=1), sim_dir)
    ccr_dir = prepare_out_dir(Path(out_dir) / "photon" / "ccr", force=True)
    run_ccr([paths["atl03"]], paths["ccr"], ccr_dir, CCRConfig(search=SearchSettings(bootstrap=50)),
            truth_path=paths["truth"], report=report, progress=progress)
