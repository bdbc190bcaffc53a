"""The Python package against the command-line tool and against known answers."""

import math
import pathlib

import numpy as np
import pytest

import shapespace
from conftest import face, read_matrix, run_distances

THREE = [face("id00_happy"), face("id01_sad"), face("id02_surprise")]


def test_pairwise_equals_the_command_bit_for_bit(shapespace_bin, tmp_path):
    run_distances(shapespace_bin, THREE, tmp_path / "out")
    names, rows = read_matrix(tmp_path / "out" / "distances.csv")
    D, pairs = shapespace.pairwise(THREE)
    assert names == ["id00_happy", "id01_sad", "id02_surprise"]
    assert D.shape == (3, 3)
    for i in range(3):
        for j in range(3):
            # the same bits (the CSV writes the shortest form that reads back exactly)
            assert D[i, j] == rows[i][j], (i, j, D[i, j], rows[i][j])
            assert D[i, j].hex() == float(rows[i][j]).hex()
    assert all(D[i, j] > 0.01 for i in range(3) for j in range(3) if i != j)
    # the pairs table has the command's pairs.csv rows (but seconds)
    csv_rows = (tmp_path / "out" / "pairs.csv").read_text().splitlines()[1:]
    assert len(pairs["a"]) == len(csv_rows) == 3
    for k, line in enumerate(csv_rows):
        cells = line.split(",")
        assert cells[0] == pairs["a"][k] and cells[1] == pairs["b"][k]
        assert float(cells[2]) == pairs["distance"][k]
        assert float(cells[3]) == pairs["cost"][k]
        assert int(cells[4]) == pairs["iterations"][k]
        assert cells[7] == pairs["status"][k]
        assert float(cells[9]) == pairs["dual_cost"][k]


def test_distance_of_two_files_equals_the_command(shapespace_bin, tmp_path):
    a, b = face("id03_neutral"), face("id04_happy")
    run_distances(shapespace_bin, [a, b], tmp_path / "out")
    _, rows = read_matrix(tmp_path / "out" / "distances.csv")
    d, record = shapespace.distance(a, b)
    assert d == rows[0][1]
    assert record["a"] == "id03_neutral" and record["b"] == "id04_happy"
    assert record["status"] == "converged"
    assert record["distance"] == d and math.sqrt(record["cost"]) == d
    assert record["iterations"] >= 1
    # the dual cost is a lower bound close to the cost (a posteriori check of the pair)
    assert abs(record["cost"] - record["dual_cost"]) / record["cost"] < 1e-3
    # the same meshes given as arrays, with the marker file the files find beside them: the
    # same bits; without it (automatic markers) another distance
    landmarks = pathlib.Path(a).parent / "landmarks.json"
    meshes = shapespace.read_mesh(a), shapespace.read_mesh(b)
    assert shapespace.distance(*meshes, landmarks=landmarks)[0] == d
    assert shapespace.distance(*meshes)[0] != d


def test_source_faces_equal_the_command_and_stay_close_to_full_resolution(shapespace_bin, tmp_path):
    a, b = face("id03_neutral"), face("id04_happy")
    run_distances(shapespace_bin, [a, b], tmp_path / "out", "--source-faces", "5000")
    _, rows = read_matrix(tmp_path / "out" / "distances.csv")
    d, record = shapespace.distance(a, b, source_faces=5000)
    assert d == rows[0][1] and record["status"] == "converged"
    full, _ = shapespace.distance(a, b)
    assert d != full and abs(d / full - 1) < 0.01
    with pytest.raises(shapespace.ShapespaceError, match="source_faces must be at least 1"):
        shapespace.distance(a, b, source_faces=0)


def test_symmetrized_distance_is_the_mean_of_both_directions():
    a, b = face("id00_neutral"), face("id00_sad")
    d_ab, _ = shapespace.distance(a, b)
    d_ba, _ = shapespace.distance(b, a)
    d_sym, _ = shapespace.distance(a, b, symmetrize=True)
    assert d_sym == 0.5 * (d_ab + d_ba)
    assert d_ab != d_ba


def boundary_vertices(F):
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return np.unique(unique[counts == 1])


def test_conformal_map_sends_the_markers_where_asked():
    V, F = shapespace.read_mesh(face("id01_neutral"))
    bnd = boundary_vertices(F)
    center, marker = 4000, int(bnd[len(bnd) // 3])
    for method in ("green", "bff"):
        uv, factors, report = shapespace.conformal_map(V, F, center=center, boundary=marker, method=method)
        assert uv.shape == (len(V), 2) and factors.shape == (len(V),)
        assert np.abs(uv[center]).max() < 1e-12, (method, uv[center])
        assert abs(uv[marker][0] - 1) < 1e-12 and abs(uv[marker][1]) < 1e-12, (method, uv[marker])
        radius = np.hypot(uv[bnd, 0], uv[bnd, 1])
        assert np.abs(radius - 1).max() < 1e-9, method
        interior = np.setdiff1d(np.arange(len(V)), bnd)
        assert np.hypot(uv[interior, 0], uv[interior, 1]).max() < 1
        assert report["center"] == center and report["boundary"] == marker
        assert report["quality"]["num_flipped"] == 0


def test_info_of_a_face():
    V, F = shapespace.read_mesh(face("id00_happy"))
    assert V.shape == (9412, 3) and F.shape == (18618, 3)
    result = shapespace.info(V, F)
    assert result["classification"]["class"] == "disk"
    report = result["report"]
    assert report["num_vertices"] == 9412 and report["num_faces"] == 18618


def test_area_preserving_map_equalizes_areas():
    V, F = shapespace.read_mesh(face("id02_neutral"))
    uv, report = shapespace.area_preserving_map(V, F)
    assert uv.shape == (len(V), 2)
    assert report["ot"]["converged"]
    assert np.hypot(uv[:, 0], uv[:, 1]).max() <= 1 + 1e-9
    # image areas proportional to the 3D areas, far more than in the conformal map
    def areas(P):
        a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1) if P.shape[1] == 3 else 0.5 * np.abs(
            (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        )
    ratio_ap = areas(uv) / areas(V)
    uv_c, _, _ = shapespace.conformal_map(V, F)
    ratio_c = areas(uv_c) / areas(V)
    spread = lambda r: np.percentile(r, 90) / np.percentile(r, 10)
    assert spread(ratio_ap) < spread(ratio_c) / 3, (spread(ratio_ap), spread(ratio_c))


def test_ot_to_weighted_points_in_the_disk():
    rng = np.random.default_rng(7)
    angle = rng.uniform(0, 2 * np.pi, 200)
    radius = np.sqrt(rng.uniform(0, 0.8, 200))
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    masses = rng.uniform(1, 3, 200)
    masses *= np.pi / masses.sum()
    heights, cell_masses, centroids, report = shapespace.ot(points, masses, tol=1e-8)
    assert report["converged"], report
    assert heights.shape == (200,) and centroids.shape == (200, 2)
    # the cells hold the masses asked for (the disk is a 512-gon: masses scaled to its area)
    rel = np.abs(cell_masses / cell_masses.sum() - masses / masses.sum()) / (masses / masses.sum())
    assert rel.max() < 1e-7
    assert report["cost"] > 0 and abs(report["cost"] - report["dual_cost"]) < 1e-6 * report["cost"]


def test_mds_recovers_euclidean_distances():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(12, 2)) * [3.0, 1.0]
    D = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2)
    coords, eigenvalues = shapespace.mds(D, dims=2)
    assert coords.shape == (12, 2) and eigenvalues.shape == (12,)
    recovered = np.linalg.norm(coords[:, None, :] - coords[None, :, :], axis=2)
    assert np.abs(recovered - D).max() < 1e-10 * D.max()
    # two positive eigenvalues, the rest zero up to round-off
    assert eigenvalues[1] > 1 and np.abs(eigenvalues[2:]).max() < 1e-9 * eigenvalues[0]


def test_errors_name_the_file(tmp_path):
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(shapespace.ShapespaceError, match="broken.obj"):
        shapespace.read_mesh(bad)
    with pytest.raises(shapespace.ShapespaceError, match="missing.obj"):
        shapespace.read_mesh(tmp_path / "missing.obj")
    with pytest.raises(shapespace.ShapespaceError, match="broken.obj"):
        shapespace.distance(face("id00_happy"), bad)
    # a failed file in pairwise leaves its row and column NaN and names it in the pairs
    D, pairs = shapespace.pairwise([face("id00_happy"), face("id01_happy"), str(bad)])
    assert math.isnan(D[0, 2]) and math.isnan(D[2, 1]) and D[0, 1] > 0
    assert list(pairs["status"]).count("failed: shape failed to prepare") == 2
    with pytest.raises(shapespace.ShapespaceError, match="tol must be in"):
        shapespace.pairwise(THREE, tol=2.0)
    with pytest.raises(shapespace.ShapespaceError, match="same shape name"):
        shapespace.pairwise([face("id00_happy"), face("id00_happy")])
    with pytest.raises(shapespace.ShapespaceError, match="expected an array of shape"):
        shapespace.info(np.zeros((4, 2)), np.zeros((1, 3), dtype=int))


def test_pairs_table_is_a_dataframe_or_a_dict():
    D, pairs = shapespace.pairwise([face("id05_happy"), face("id05_sad")])
    try:
        import pandas
    except ImportError:
        assert isinstance(pairs, dict) and list(pairs) == list(shapespace.PAIR_COLUMNS)
    else:
        assert isinstance(pairs, pandas.DataFrame) and list(pairs.columns) == list(shapespace.PAIR_COLUMNS)
    assert pairs["distance"][0] == D[0, 1] == D[1, 0]


def test_shard_pairs_cover_all_pairs():
    pairs = [p for k in range(1, 4) for p in shapespace.shard_pairs(5, k, 3)]
    assert pairs == [(s, t) for t in range(5) for s in range(t)]
    assert [len(shapespace.shard_pairs(5, k, 3)) for k in range(1, 4)] == [3, 3, 4]
