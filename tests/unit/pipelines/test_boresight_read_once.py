"""``calidar boresight`` decompresses every point once (issue 32): pass 2 and the overlap-quality
stages read what pass 1 kept (ingest/held.py HeldFiles), and give what reading the files
again gives, bit for bit."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from calidar.io.trajectory import read_trajectory
from calidar.ingest.measure import measure_lines
from calidar.ingest.strips import StripIngest
from calidar.ingest.settings import IngestSettings
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config


@pytest.fixture(scope="module")
def survey(tmp_path_factory) -> Path:
    res = simulate_survey(survey_config("uav", seed=12, density=0.02, directions="cross"))
    return res.write(tmp_path_factory.mktemp("read_once") / "sim")


def _run(sim: Path, options: IngestSettings):
    paths = sorted((sim / "strips").glob("*.laz"))
    traj, sensor = read_trajectory(sim / "sbet.out"), Sensor.read(sim / "sensor.toml")
    strips, _, source, _ = StripIngest(options).read(paths, traj, sensor)
    moved = replace(sensor, boresight_roll=sensor.boresight_roll + np.radians(0.05))
    stages = measure_lines(source, sensor, [None, (moved, traj)])
    return paths, strips, source, stages


def test_each_point_decompressed_once_and_every_output_as_read_twice(survey, monkeypatch):
    import calidar.ingest.footprints as ingest
    import calidar.ingest.source as source_module

    _, again, _, stages_again = _run(survey, IngestSettings(budget_points=20_000, hold_bytes=0))
    reads = []
    real = ingest.iter_las_chunks
    for module in (ingest, source_module):  # pass 1 reads in the one, pass 2 and the stages in the other
        monkeypatch.setattr(module, "iter_las_chunks", lambda path, *a, **k: reads.append(path) or real(path, *a, **k))
    paths, held, source, stages = _run(survey, IngestSettings(budget_points=20_000))
    assert sorted(reads) == sorted(paths)  # each file decompressed once, by pass 1
    assert source.held is not None and source.held.complete == set(paths)
    assert [s.id for s in held] == [s.id for s in again] and len(held) >= 3
    for a, b in zip(held, again):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.time, b.time)
    assert len(stages) == 2 and all(len(pairs) >= 2 for pairs in stages)
    for pairs, pairs_again in zip(stages, stages_again):
        assert [q.to_dict() for q in pairs] == [q.to_dict() for q in pairs_again]
    assert stages[0][0].to_dict() != stages[1][0].to_dict()  # the stages differ: the moved mounting is seen
    folder = source.held.folder
    assert folder.exists() and source.held.points.nbytes == 25 * sum(source.counts.values())
    source.held.close()
    assert not folder.exists()


def test_spans_off_the_chunks_and_other_fields_are_read_from_the_file(survey):
    paths, _, source, _ = _run(survey, IngestSettings(budget_points=20_000, chunk_points=3_000))
    f = source.files[0]
    assert source.held.chunks(f.path, (0, None)) is not None
    assert source.held.chunks(f.path, (1_000, None)) is None  # not a chunk's first point
    whole = [(c.xyz, t) for _, c, _, t in source.chunks(files=[f], span=(3_000, 9_000))]
    source.held.complete.clear()  # read the file instead
    read = [(c.xyz, t) for _, c, _, t in source.chunks(files=[f], span=(3_000, 9_000))]
    assert len(whole) == len(read) == 2
    for (x, t), (y, u) in zip(whole, read):
        assert np.array_equal(x, y) and np.array_equal(t, u)


def test_held_folder_is_a_registered_temporary():
    """Removed with its object, and by outputs.remove_temporaries (a command ending while reader
    threads still hold it: the CLI's os._exit runs no finalizer)."""
    from calidar import outputs
    from calidar.ingest.held import HeldFiles

    held = HeldFiles()
    (held.folder / "held_0.bin").write_bytes(b"0" * 10)
    assert str(held.folder) in outputs._TEMPORARIES
    outputs.remove_temporaries()
    assert not held.folder.exists()
    again = HeldFiles()
    folder = again.folder
    del again
    assert not folder.exists() and str(folder) not in outputs._TEMPORARIES


def test_released_held_folder_goes_in_a_thread_registered_until_gone(monkeypatch):
    """HeldFiles.release (the last pass read it): removed by a thread beside what follows; until
    it is gone it stays a registered temporary (an interruption meanwhile removes it as every
    temporary); finish_removals waits for it; a second release does nothing."""
    import threading

    from calidar import outputs
    from calidar.ingest.held import HeldFiles

    outputs.finish_removals()  # an earlier test's (a library call leaves them to run)
    go, real = threading.Event(), outputs._remove
    monkeypatch.setattr(outputs, "_remove", lambda tmp: go.wait(30) and real(tmp))
    held = HeldFiles()
    (held.folder / "held_0.bin").write_bytes(b"0" * 10)
    held.complete.add(Path("a.laz"))
    held.release()
    assert held.folder.exists() and str(held.folder) in outputs._TEMPORARIES
    assert [t.name for t in outputs._REMOVALS] == ["calidar-remove"] and not held.complete
    held.release()
    assert len(outputs._REMOVALS) == 1
    go.set()
    outputs.finish_removals()
    assert not held.folder.exists() and str(held.folder) not in outputs._TEMPORARIES
    assert outputs._REMOVALS == []


def test_calibrate_strips_releases_the_held_points_after_the_last_pass(survey, monkeypatch):
    """calibrate_strips drops the held points once the quality stages have read them (released:
    removed beside the report); the results' strips are then read from the files, as written
    before."""
    import calidar
    from calidar import outputs
    from calidar.ingest.held import HeldFiles

    released, real = [], HeldFiles.release
    monkeypatch.setattr(HeldFiles, "release", lambda self: released.append(self.folder) or real(self))
    paths = sorted((survey / "strips").glob("*.laz"))
    run = calidar.calibrate_strips(paths, survey / "sbet.out", survey / "sensor.toml")
    outputs.finish_removals()
    assert run.inputs.source.held is None and len(released) == 1 and not released[0].exists()
    out = run.write(survey.parent / "cal_released", strips=True)
    strips = [p for p in out if p.name.startswith("strip_") and p.stat().st_size > 0]
    assert len(strips) >= 3 and {p.name for p in out} >= {"sensor.toml", "solution.json"}
