"""The same ingest on the local process scheduler and on a real dask.distributed cluster: identical bytes."""

import os

from distributed import LocalCluster

from pipeline.io.files import write_parquet
from pipeline.io.gait_table import to_table
from pipeline.ingest.run import run_ingest


def test_local_scheduler_and_distributed_cluster_give_identical_parquet(tmp_path, full_ingest, manifests, skeleton,
                                                                       ingest_config):
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        windows, report = run_ingest(list(manifests.values()), skeleton, ingest_config,
                                     scheduler_address=cluster.scheduler_address, progress=False)
    out = tmp_path / "distributed.parquet"
    write_parquet(to_table(windows, skeleton, ingest_config.window), out)
    assert report == full_ingest["report"]
    assert out.read_bytes() == full_ingest["path"].read_bytes()


def test_rewriting_gives_the_same_bytes(tmp_path, full_ingest, skeleton, ingest_config):
    again = tmp_path / "again.parquet"
    write_parquet(to_table(full_ingest["windows"], skeleton, ingest_config.window), again)
    assert again.read_bytes() == full_ingest["path"].read_bytes()
    assert not [p for p in os.listdir(tmp_path) if ".tmp" in p], "temporary files left behind"
