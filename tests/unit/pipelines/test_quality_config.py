"""``calidar quality``'s options parsed once, at the CLI (issue 29): the pipeline's ``measure`` takes one
frozen, checked QualityConfig (the swath difference's QualitySettings, the classes, the point options,
the chunk size) and the boresight pipeline hands its quality stages a QualitySettings."""

from __future__ import annotations

import dataclasses
import inspect

import pytest

from calidar.errors import InputError
from calidar.io.las import PointOptions
from calidar.pipelines.quality import QualityConfig, measure
from calidar.strips.quality import QualitySettings


def test_the_configuration_is_typed_frozen_and_checked():
    config = QualityConfig(QualitySettings(cell_m=1.5), (6, 2, 6), PointOptions("EPSG:32632"), 1000)
    assert config.classes == (2, 6) and config.settings.cell_m == 1.5 and config.points.crs is not None
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.classes = (2,)
    with pytest.raises(InputError, match="--classes"):
        QualityConfig(classes=(2, 300))
    with pytest.raises(InputError, match="--classes"):
        QualityConfig(classes=())
    with pytest.raises(ValueError, match="chunk_points"):
        QualityConfig(chunk_points=0)
    with pytest.raises(TypeError):
        QualityConfig(settings=1.5)
    assert list(inspect.signature(measure).parameters) == ["paths", "config"]


def test_the_cli_builds_it_once_from_its_options(cli, monkeypatch, tmp_path):
    seen = []

    def fake_measure(paths, config):
        seen.append(config)
        raise InputError(paths[0], "point_source_id", "stop here")

    monkeypatch.setattr("calidar.cli.quality.measure", fake_measure)
    code, _, err = cli("quality", tmp_path / "a.laz", tmp_path / "b.laz", "--cell", "1.5", "--classes", "6,2",
                       "--crs", "EPSG:32632", "--geoid-undulation", "47.5")
    assert code == 1 and "stop here" in err
    (config,) = seen
    assert isinstance(config, QualityConfig)
    assert (config.settings.cell_m, config.classes, config.points.geoid_undulation_m) == (1.5, (2, 6), 47.5)
    assert config.settings == QualitySettings(cell_m=1.5)


def test_the_boresight_quality_stages_take_the_settings_whole(monkeypatch):
    from types import SimpleNamespace

    from calidar.ingest import measure as ingest_measure
    from calidar.pipelines import boresight_outputs

    got = []
    monkeypatch.setattr(ingest_measure, "measure_lines", lambda *a: got.append(a) or [[], []])
    inputs = SimpleNamespace(source=None, nominal=None, trajectory=None)
    boresight_outputs.quality_stages(inputs, SimpleNamespace(sensor=None), None)
    assert isinstance(got[0][-1], QualitySettings) and got[0][-1] == QualitySettings()
