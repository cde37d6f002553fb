"""Registering a given centerline onto the lumen (curves made on another surface)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from sim4endor.vessels.build import BuildParams, build_vessel
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.register import (
    CenterlineRegistrationError,
    RegistrationParams,
    register_centerline,
    signed_distance,
)
from sim4endor.vessels.walls import WallParams

R = 1.5e-3
L = 20e-3


def tube() -> trimesh.Trimesh:
    """A capped straight tube along z (m), axis at x = y = 0."""
    return trimesh.creation.cylinder(radius=R, height=L, sections=32).subdivide_to_size(1.5e-3)


def offset_curve(offset: float, overhang: float = 0.0, name: str = "curve_a") -> CenterlineGraph:
    """A one-branch curve along the tube, ``offset`` radii off the axis in a turning direction."""
    z = np.linspace(-L / 2 - overhang, L / 2 + overhang, 61)
    turn = np.pi * (z + L / 2) / L
    nodes = np.column_stack([offset * R * np.cos(turn), offset * R * np.sin(turn), z])
    edges = np.column_stack([np.arange(60), np.arange(1, 61)])
    return CenterlineGraph(nodes, np.full(61, R), edges, branch=np.zeros(61, dtype=np.int64),
                           branch_names=(name,))


def test_signed_distance_is_exact_and_ignores_winding() -> None:
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    points = np.array([[0.0, 0.0, 0.0], [0.5, 0.2, 0.0], [2.0, 0.0, 0.0], [1.5, 1.5, 0.0],
                       [2.0, 2.0, 2.0]])
    expected = [1.0, 0.5, -1.0, -np.sqrt(0.5), -np.sqrt(3.0)]
    np.testing.assert_allclose(signed_distance(box, points), expected, atol=1e-12)
    inverted = trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False)
    np.testing.assert_allclose(signed_distance(inverted, points), expected, atol=1e-12)


@pytest.mark.parametrize("offset", [0.5, 1.3])  # off-centre inside, and outside the lumen
def test_offset_curve_is_registered_onto_the_axis(offset: float) -> None:
    given = offset_curve(offset, overhang=2e-3)
    registered, report = register_centerline(given, tube())
    # Within a radius of a cap the cap bounds the clearance, so only the interior is centred.
    interior = np.abs(registered.nodes[:, 2]) < L / 2 - R
    off_axis = np.linalg.norm(registered.nodes[:, :2], axis=1)
    assert off_axis[interior].max() < 0.1 * R and off_axis.max() < R
    assert np.abs(registered.nodes[:, 2]).max() < L / 2  # the overhanging ends are trimmed
    past_caps = int(np.sum(np.abs(given.nodes[:, 2]) > L / 2))
    # Past the caps, plus the nodes in the caps with less than half a radius of clearance.
    assert past_caps + 2 <= report.trimmed_points <= past_caps + 6
    assert registered.num_components() == 1 and len(registered.terminal_nodes()) == 2
    assert np.all(registered.radii[interior] > 0.95 * R) and np.all(registered.radii <= R)
    assert report.offset_median_r == pytest.approx(offset, abs=0.1)
    assert report.moved == report.points
    if offset > 1:
        assert report.given_outside == 61
    else:
        assert report.given_outside == past_caps and report.given_within_clearance < 10
    assert registered.branch_names == ("curve_a",)


def test_curve_beside_the_lumen_is_an_error_naming_it() -> None:
    far = offset_curve(0.0, name="Centerline curve (7)")
    far = CenterlineGraph(far.nodes + np.array([8e-3, 0.0, 0.0]), far.radii, far.edges,
                          branch=far.branch, branch_names=far.branch_names)
    with pytest.raises(CenterlineRegistrationError, match=r"Centerline curve \(7\)"):
        register_centerline(far, tube(), RegistrationParams(min_search=2e-3))


def test_build_checks_the_registered_axis_and_reports_the_given_one(tmp_path: Path) -> None:
    vessel = build_vessel(
        tube(), name="reg", out_dir=tmp_path / "reg", centerline=offset_curve(0.8),
        registration=RegistrationParams(), params=BuildParams(wall=WallParams(workers=1)),
        progress=False, cache=False,
    )
    checks = vessel.manifest.checks
    assert checks["lumen_open"] == 1.0 and checks["wall_closed"] >= 0.99
    assert checks["lumen_open_given_centerline"] < 0.5
    report = vessel.manifest.build["centerline_registration"]["report"]
    assert report["offset_median_r"] == pytest.approx(0.8, abs=0.1)
    interior = np.abs(vessel.centerline.nodes[:, 2]) < L / 2 - R
    assert np.linalg.norm(vessel.centerline.nodes[interior, :2], axis=1).max() < 0.1 * R
