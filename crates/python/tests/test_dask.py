"""pairwise on a real dask.distributed cluster (two worker processes) against the command."""

import pytest

import shapespace
from conftest import face, read_matrix, run_distances

distributed = pytest.importorskip(
    "distributed", reason="DASK NOT INSTALLED: the Dask test is skipped (pip install dask distributed)"
)

FOUR = [face("id06_happy"), face("id06_sad"), face("id07_neutral"), face("id08_surprise")]


def test_pairwise_on_a_local_cluster_equals_the_command(shapespace_bin, tmp_path):
    run_distances(shapespace_bin, FOUR, tmp_path / "out")
    names, rows = read_matrix(tmp_path / "out" / "distances.csv")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            D, pairs = shapespace.pairwise(FOUR, client=client, tiles=4)
            # the tiles ran in the worker processes (each keeps the shapes it prepared), not here
            prepared = client.run(lambda: len(__import__("shapespace")._WORKER_PREPARED))
    assert len(prepared) == 2 and sum(prepared.values()) >= 1, prepared
    assert not shapespace._WORKER_PREPARED
    assert names == ["id06_happy", "id06_sad", "id07_neutral", "id08_surprise"]
    for i in range(4):
        for j in range(4):
            assert D[i, j].hex() == float(rows[i][j]).hex(), (i, j)
    assert list(pairs["a"]) == [r.split(",")[0] for r in (tmp_path / "out" / "pairs.csv").read_text().splitlines()[1:]]
    # the same matrix in process
    D_local, _ = shapespace.pairwise(FOUR)
    assert (D_local == D).all()


class _DieOnceInATile(distributed.WorkerPlugin):
    """Kills the worker process the first time any worker starts a tile (an exclusive marker
    file makes it once across restarts): the nanny restarts the worker and the scheduler reruns
    the tile elsewhere."""

    def __init__(self, marker):
        self.marker = str(marker)

    def transition(self, key, start, finish, **kwargs):
        import os

        name = key[0] if isinstance(key, tuple) else key
        if finish == "executing" and str(name).startswith("_worker_tile"):
            try:
                os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                return
            os._exit(1)


def test_a_worker_dying_in_a_tile_changes_no_result(shapespace_bin, tmp_path):
    run_distances(shapespace_bin, FOUR, tmp_path / "out")
    names, rows = read_matrix(tmp_path / "out" / "distances.csv")
    marker = tmp_path / "died"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            client.register_plugin(_DieOnceInATile(marker))
            D, _ = shapespace.pairwise(FOUR, client=client, tiles=4)
    assert marker.exists(), "no worker died: the test did not test anything"
    for i in range(4):
        for j in range(4):
            assert D[i, j].hex() == float(rows[i][j]).hex(), (i, j)
