"""The overlap-quality stages re-georeferenced in one numba pass per chunk (issue 32;
calidar.ingest.regeoref): the coordinates of every stage equal, bit for bit, the model-by-model
path (inverse, then a forward per mounting, then the move through the tile Jacobians), and the
stages' pairs equal those of that path on a small simulated survey."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from calidar import georef
from calidar.ingest.measure import measure_lines
from calidar.ingest.regeoref import moved_versions
from calidar.ingest.settings import IngestSettings
from calidar.ingest.strips import StripIngest
from calidar.ingest.times import points_tile_linear
from calidar.io.trajectory import read_trajectory
from calidar.sensor import Sensor
from calidar.sim.survey import simulate_survey, survey_config


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    sim = simulate_survey(survey_config("uav", seed=5, density=0.02, directions="cross")).write(
        tmp_path_factory.mktemp("fused") / "sim")
    paths = sorted((sim / "strips").glob("*.laz"))
    traj, sensor = read_trajectory(sim / "sbet.out"), Sensor.read(sim / "sensor.toml")
    _, _, source, _ = StripIngest(IngestSettings(budget_points=20_000)).read(paths, traj, sensor)
    moved = replace(sensor, boresight_roll=sensor.boresight_roll + np.radians(0.05), lever_arm_z=0.03)
    wave = 0.04 * np.sin(np.linspace(0, 6, len(traj)))
    corrected = replace(traj, height=traj.height + wave, roll=traj.roll + 1e-5 * wave)  # another trajectory
    models = [None, (moved, traj), (replace(moved, boresight_yaw=moved.boresight_yaw - 1e-4), corrected)]
    yield source, sensor, traj, models
    source.held.close()


def _model_by_model(traj, nominal, models, t, lin):
    """What calidar.ingest.source.line_chunks did before the fused pass."""
    ecef = lin.near_ecef()
    v_s = georef.scanner_vectors(traj, nominal, t, ecef)
    return [None if m is None else lin.moved(georef.reforward(nominal, m[0], m[1], t, v_s) - ecef) for m in models]


def test_every_stage_bit_for_bit_the_model_by_model_path(run):
    source, sensor, traj, models = run
    n = 0
    for _, chunk, _, t in source.chunks(("classification", "return_number", "number_of_returns")):
        lin = points_tile_linear(chunk)
        fused, want = moved_versions(traj, sensor, models, t, lin), _model_by_model(traj, sensor, models, t, lin)
        assert fused[0] is None and want[0] is None
        for a, b in zip(fused[1:], want[1:]):
            assert a.shape == (len(t), 3) and np.array_equal(a, b)  # not within a tolerance: equal
        assert not np.array_equal(fused[1], fused[2])  # the stages differ
        assert np.abs(fused[1] - chunk.xyz).max() > 0.01  # and differ from the delivered points
        n += len(t)
    assert n > 10_000


def test_other_range_models_and_a_third_trajectory_go_the_long_way(run):
    source, sensor, traj, models = run
    _, chunk, _, t = next(source.chunks(("classification",)))
    lin = points_tile_linear(chunk)
    assert moved_versions(traj, sensor, [None, (replace(sensor, range_offset=0.02), traj)], t, lin) is None
    third = replace(traj, height=traj.height + 0.01)
    assert moved_versions(traj, sensor, [*models, (sensor, third)], t, lin) is None
    assert moved_versions(traj, sensor, [None], t, lin) == [None]


def test_stages_equal_the_model_by_model_path(run, monkeypatch):
    import calidar.ingest.regeoref as regeoref

    source, sensor, _, models = run
    fused = measure_lines(source, sensor, models)
    monkeypatch.setattr(regeoref, "moved_versions", lambda *a: None)  # the model-by-model path in line_chunks
    unfused = measure_lines(source, sensor, models)
    assert len(fused) == 3 and all(len(pairs) >= 2 for pairs in fused)
    for a, b in zip(fused, unfused):
        assert [q.to_dict() for q in a] == [q.to_dict() for q in b]
        assert all(np.array_equal(p.grid, q.grid, equal_nan=True) for p, q in zip(a, b))
    assert fused[1][0].to_dict() != fused[0][0].to_dict() != fused[2][0].to_dict()


def test_calidar_quality_equals_its_unfused_path(run, monkeypatch):
    """``calidar quality`` (pipelines.quality.measure) with the fused kernels (moments, counts), the
    next chunk decompressed ahead and the pairs in two threads equals the numpy path, one pair at
    a time, on the same files: every pair, grid and line precision."""
    import calidar.ingest.lines as lines
    import calidar.strips.distribute as distribute
    import calidar.strips.moments_kernel as kernel
    from calidar.pipelines.quality import measure

    source, *_ = run
    paths = [f.path for f in source.files]
    monkeypatch.setattr(distribute, "IN_PROCESS_THREADS", 2)
    fused = measure(paths)
    monkeypatch.setattr(kernel, "dense_moments", lambda *a: None)
    monkeypatch.setattr(kernel, "dense_cell_counts", lambda *a: None)
    monkeypatch.setattr(distribute, "IN_PROCESS_THREADS", 1)
    monkeypatch.setattr(lines, "prefetched", lambda items: items)
    unfused = measure(paths)
    assert len(fused[2]) >= 2 and [q.to_dict() for q in fused[2]] == [q.to_dict() for q in unfused[2]]
    assert all(np.array_equal(p.grid, q.grid, equal_nan=True) for p, q in zip(fused[2], unfused[2]))
    assert [p.to_dict() for p in fused[5]] == [p.to_dict() for p in unfused[5]]
    assert fused[3] == unfused[3]


def test_only_the_selected_points_are_re_georeferenced(run, monkeypatch):
    """The stages inside boresight re-georeference only the points each line's selection keeps
    (ground of a classified line), each moved as it is among all the chunk's points (its tiles laid
    over all of them): the kernel's rows at those positions equal the full kernel's bit for bit
    (the others NaN), a
    time outside the trajectory among the others still stops the run, and the stages equal those
    of every candidate re-georeferenced."""
    import calidar.ingest.stages as stages
    from calidar.errors import InputError

    source, sensor, traj, models = run
    _, chunk, ids, t = next(source.chunks(("classification", "return_number", "number_of_returns")))
    chosen = source.quality.chosen(source.names)
    keep = stages.chosen_points(chosen)(chunk, ids)
    take = np.flatnonzero(keep)
    assert 0 < take.size < 0.9 * len(t)  # the selection leaves points out
    lin = points_tile_linear(chunk)
    full, some = moved_versions(traj, sensor, models, t, lin), moved_versions(traj, sensor, models, t, lin, take)
    assert all(np.array_equal(a[take], b[take]) for a, b in zip(full[1:], some[1:]))
    assert all(np.isnan(b[~keep]).all() for b in some[1:])  # the others not computed
    late = t.copy()
    late[np.flatnonzero(~keep)[0]] = traj.time[-1] + 10.0  # a point left out, after the trajectory
    with pytest.raises(InputError, match="outside the trajectory"):
        moved_versions(traj, sensor, models, late, lin, take)
    selected = measure_lines(source, sensor, models)
    monkeypatch.setattr(stages, "chosen_points", lambda chosen: lambda chunk, ids: np.ones(ids.size, bool))
    every = measure_lines(source, sensor, models)
    for a, b in zip(selected, every):
        assert [q.to_dict() for q in a] == [q.to_dict() for q in b]
        assert all(np.array_equal(p.grid, q.grid, equal_nan=True) for p, q in zip(a, b))
