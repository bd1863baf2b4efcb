"""Fleet replay on a dask.distributed cluster (a LocalCluster on loopback) gives the local run's outputs."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import distributed  # the 'fleet' extra, installed with 'dev': no skip if it is missing
import pytest

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.replay import replay_many

SITL_LOGS = Path(__file__).resolve().parents[2] / "sitl_logs"
VOLATILE = {"out_dir", "elapsed_s"}  # where and how fast, not what


def _summary(folder: Path) -> list[dict[str, str]]:
    with (folder / "fleet_summary.csv").open(encoding="utf-8") as handle:
        return [{k: v for k, v in row.items() if k not in VOLATILE} for row in csv.DictReader(handle)]


def test_a_dask_cluster_writes_what_the_local_run_writes(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("flight_F4.1_calm.csv", "flight_F4.1_moderate.tlog", "flight_F4.1_moderate.bin"):
        shutil.copy(SITL_LOGS / name, logs / name)
    (logs / "empty.tlog").write_bytes(b"")  # an ERROR row on both paths
    paths = sorted(logs.iterdir())
    params, profile = load_motor_params(), load_profile("flight")
    local = replay_many(paths, tmp_path / "local", params, profile, jobs=1)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        remote = replay_many(
            paths, tmp_path / "dask", params, profile, dask_scheduler=cluster.scheduler_address
        )
    assert [r.error is None for r in remote.results] == [r.error is None for r in local.results]
    assert sum(r.error is not None for r in remote.results) == 1
    remote_rows, local_rows = _summary(tmp_path / "dask"), _summary(tmp_path / "local")
    assert len(remote_rows) == len(local_rows)
    for theirs, ours in zip(remote_rows, local_rows):  # field by field: a failure names what differs
        assert theirs == ours, {k: (theirs[k], ours.get(k)) for k in theirs if theirs[k] != ours.get(k)}
    for folder in (tmp_path / "local").iterdir():
        if not folder.is_dir():
            continue
        for name in ("diagnosis.csv", "events.jsonl"):
            assert (tmp_path / "dask" / folder.name / name).read_bytes() == (folder / name).read_bytes()


def test_without_dask_installed_the_error_names_the_extra(tmp_path: Path, monkeypatch) -> None:
    import builtins

    real_import = builtins.__import__

    def no_distributed(name, *args, **kwargs):
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError("No module named 'distributed'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_distributed)
    from mav_motor_health.errors import DataError

    with pytest.raises(DataError, match=r"mav-motor-health\[fleet\]"):
        replay_many(
            [SITL_LOGS / "flight_F4.1_calm.csv"] * 2,
            tmp_path / "out",
            load_motor_params(),
            load_profile("flight"),
            dask_scheduler="tcp://127.0.0.1:1",
        )
