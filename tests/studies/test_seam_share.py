"""The share of error near UV seams (hzval.studies.seam_share) on a model whose seams are known: the cube's
twelve edges are seams (its faces are rotated and mirrored as an unwrap does), its faces' diagonals
are not; the plane has none."""

import numpy as np
import pytest

from hzval.geometry import model
from hzval.studies import seam_share


def test_distances_to_the_cubes_seams():
    m = model.cube()  # edge length 1, centred at the origin
    assert m.seam_edges == 12
    centres = np.array([[0.5, 0, 0], [-0.5, 0, 0], [0, 0.5, 0], [0, -0.5, 0], [0, 0, 0.5], [0, 0, -0.5]])
    # a face's centre lies on its diagonal (an edge, not a seam): half an edge from the nearest seam
    np.testing.assert_allclose(seam_share.seam_distance_texels(m, centres, 0.1), 5.0, rtol=1e-6)
    ends = model.seam_edge_ends(m)
    mid = 0.5 * (m.positions[ends[:, 0]] + m.positions[ends[:, 1]])
    assert seam_share.seam_distance_texels(m, mid, 0.1).max() < 1e-9
    off = np.array([[0.5, 0.3, 0.5 - 0.02]])  # on the top face's edge to +x, 0.02 in: 2 texels
    assert seam_share.seam_distance_texels(m, off, 0.01)[0] == pytest.approx(2.0, abs=0.2)
    assert np.isnan(seam_share.seam_distance_texels(m, np.full((1, 3), np.nan), 0.1)[0])


def test_a_plane_has_no_seams():
    d = seam_share.seam_distance_texels(model.plane(), np.zeros((3, 3)), 0.1)
    assert np.isinf(d).all()


def test_shares_of_error_and_pixels():
    error = np.array([1.0, 1.0, 2.0, 0.0, 9.0])
    near = np.array([True, False, True, False, True])
    keep = np.array([True, True, True, True, False])  # the last pixel is not seen
    s = seam_share.shares(error, near, keep)
    assert s["error_share"] == pytest.approx(3.0 / 4.0) and s["pixel_share"] == pytest.approx(0.5)
    assert seam_share.shares(np.zeros(5), near, keep)["error_share"] is None
