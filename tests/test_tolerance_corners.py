"""The worst corner of a tolerance study: every corner of the box is evaluated up to the
documented limit whether the variants' plants were mapped or built exactly, and the text
says how many (and why only one, beyond the limit)."""

from __future__ import annotations

import numpy as np
import pytest

from .conftest import SCENES

TOLERANCES = ('\n[tolerances]\nmotor.resistance = "+-10 %"\nload.inertia = "+-20 %"\n'
              'motor.torque_constant = { sigma = "2 %", min = "x0.95", max = "x1.05" }\n')


@pytest.fixture(scope="module")
def corner_scene(tmp_path_factory):
    from servo_toolkit.scene.loader import load_scene
    path = tmp_path_factory.mktemp("corners") / "corners.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + TOLERANCES)
    return load_scene(path)


def test_variants_built_exactly_still_evaluate_every_corner(corner_scene, monkeypatch):
    """Maps that do not verify make the study build every variant exactly; its worst corner
    then comes from all 2^3 corners built exactly too, not from the one the regression's
    signs point to. It is the corner (and the margin) the mapped study finds, and no corner
    evaluated on its own does worse."""
    import servo_toolkit.loop.variant_plants as vp
    from servo_toolkit.loop import design
    from servo_toolkit.studies.tolerances import tolerance_study
    designed = design(corner_scene, progress=False)
    kw = dict(samples=16, progress=False, duration=0.02)
    mapped = tolerance_study(corner_scene, designed, **kw)
    keyed = vp.keyed_plants
    monkeypatch.setattr(vp, "keyed_plants", lambda *a, **k: keyed(*a, **{**k, "rtol": -1.0}))  # no map verifies
    exact = tolerance_study(corner_scene, designed, **kw)
    assert mapped.settings["plants"] == "separable" and exact.settings["plants"] == "exact"
    assert exact.worst.corners == mapped.worst.corners == 8
    for study in (mapped, exact):
        w = study.worst
        assert (w.corners, w.total) == (8, 8) and "(8 corners evaluated)" in study.table()
        assert study.to_dict()["worst_corner"]["corners_total"] == 8
    assert exact.worst.values == mapped.worst.values
    assert exact.worst.score == pytest.approx(mapped.worst.score, rel=1e-3)
    assert any("built its 8 corners exactly" in n for n in exact.notes)
    # each corner on its own, built exactly: none is closer to a requirement than the one named
    from servo_toolkit.loop.robustness import variant_figures
    from servo_toolkit.plant.linear import DEFAULT_STRUCTURAL_DAMPING
    from servo_toolkit.studies.tolerances.corner import _score
    items = corner_scene.tolerances.items
    grid = np.array(np.meshgrid(*[t.ends for t in items], indexing="ij")).reshape(len(items), -1)
    vals = {t.key: grid[j] for j, t in enumerate(items)}
    f_req = next(r.required for r in designed.requirements if r.name == "bandwidth")
    figs = variant_figures(corner_scene, designed.parameters, designed.controller, vals, f_req, progress=False,
                           plants=keyed(corner_scene, designed.parameters, vals, DEFAULT_STRUCTURAL_DAMPING, exact=True))
    score, _ = _score(list(exact.requirements), figs)
    assert exact.worst.score == pytest.approx(score.min(), rel=1e-9)


@pytest.mark.parametrize("corners, total, words", [
    (1, 1, "(1 corner evaluated)"),
    (2, 2, "(2 corners evaluated)"),
    (1, 4096, "(1 of 4096 corners evaluated, the one the regression's signs point to (every corner up to 1024))"),
])
def test_the_text_says_how_many_corners_were_evaluated_and_why_only_one(corners, total, words):
    from servo_toolkit.core.yields import Yield
    from servo_toolkit.scene.tolerances import Tolerance, Tolerances
    from servo_toolkit.studies.tolerances import ToleranceResult, WorstCorner
    items = (Tolerance("motor.resistance", "ohm", 0.5, "uniform", 0.5, 0.7),)
    worst = WorstCorner({"motor.resistance": 0.7}, 0.3, "phase_margin", corners, {}, total=total)
    every = Yield.of("all", "every requirement", 4, 4, 0.95, None)
    result = ToleranceResult("demo", Tolerances(items, samples=4), {"motor.resistance": np.full(4, 0.6)}, {}, None,
                             (), {}, (every,), (), worst, {"method": "lhs"})
    assert f"worst corner over the linear figures {words}: phase_margin margin 30 %" in result.table()
    assert worst.to_dict()["corners_total"] == total
