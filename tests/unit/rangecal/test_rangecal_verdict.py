"""The range calibration's verdict and the unit check, against simulations whose truth is known."""

from dataclasses import replace

import pytest

from calidar.errors import InputError
from calidar.rangecal import calibrate, truth_parameters
from calidar.rangecal.fit import target_distances
from calidar.rangecal.units import check_units, unit_of_ratio
from calidar.rangecal.verdict import range_verdict
from calidar.sim.total_station import TotalStationSimConfig, simulate_total_station


def _findings(verdict):
    return {f.check: f for f in verdict.findings}


def test_clean_simulation_passes_every_check():
    obs, truth = simulate_total_station(0)
    res = calibrate(obs, tolerance_m=0.2)
    v = range_verdict(res, truth_parameters(truth))
    f = _findings(v)
    assert v.status == "pass", v.to_dict()
    assert {"range correction", "residuals vs the stated precisions", "outliers", "acceptance",
            "against the simulation's truth"} <= set(f)
    off = res.solution.values["range_offset"] * 1e3
    assert f"{abs(off):.2f} ± {res.solution.sigma['range_offset'] * 1e3:.2f} mm" in f["range correction"].detail


def test_gross_error_and_tight_tolerance_are_named():
    obs, truth = simulate_total_station(4, TotalStationSimConfig(outliers=1, range_offset_m=0.03, range_scale_ppm=0.0))
    res = calibrate(obs, tolerance_m=0.01)
    f = _findings(range_verdict(res))
    assert f["outliers"].status == "warn" and f"point {res.fit.rejected[0]['point']}" in f["outliers"].detail
    assert f["acceptance"].status == "fail" and "beyond the tolerance of 10.00 mm" in f["acceptance"].detail
    assert f["acceptance"].action


def test_optimistic_precisions_fail_the_global_test():
    obs, _ = simulate_total_station(9)
    setups = [replace(s, angle_sigma=s.angle_sigma / 10, distance_sigma_m=s.distance_sigma_m / 10,
                      distance_sigma_ppm=s.distance_sigma_ppm / 10) for s in obs.setups]
    res = calibrate(replace(obs, scanner_sigma=0.2e-3, setups=setups))
    f = _findings(range_verdict(res))
    g = f["residuals vs the stated precisions"]
    assert g.status in ("warn", "fail") and "larger than stated" in g.detail and "scanner_sigma_mm" in g.action
    assert f["outliers"].status == "fail"  # snooping hit its 20 % limit: do not use the result


def test_pessimistic_precisions_warn_that_sigma_keeps_them():
    obs, _ = simulate_total_station(3)
    res = calibrate(replace(obs, scanner_sigma=obs.scanner_sigma * 4))
    g = _findings(range_verdict(res))["residuals vs the stated precisions"]
    assert g.status == "warn" and "smaller than stated" in g.detail


@pytest.mark.parametrize("factor,unit,field", [(1000.0, "millimetres", "scanner_m"), (100.0, "centimetres", "scanner_m"),
                                               (1 / 0.3048, "feet", "scanner_m"), (1e-3, "millimetres", "slope_m")])
def test_unit_slips_by_magnitude(factor, unit, field):
    obs, _ = simulate_total_station(1)
    bad = replace(obs, scanner=obs.scanner * factor)
    with pytest.raises(InputError, match=f"{field}.*look.* like {unit}"):
        check_units(bad, target_distances(bad)[0])


def test_metres_pass_and_ratios_name_units():
    obs, _ = simulate_total_station(2)
    check_units(obs, target_distances(obs)[0])  # no error
    assert unit_of_ratio(1 / 0.0254) == "inches" and unit_of_ratio(1.3) is None
    with pytest.raises(InputError, match="agree within a few per cent"):
        bad = replace(obs, scanner=obs.scanner * 7.0)
        check_units(bad, target_distances(bad)[0])
