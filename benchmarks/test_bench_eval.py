"""The evaluation of four rendered sequences in a local process pool and on a Dask LocalCluster
(two workers each, one thread, workers' glibc malloc thresholds restored by the job)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from fisheyemotion.eval.evaluate import evaluate

import fisheyemotion as fm
from fisheyemotion import synth

CAM = fm.calib.load(__file__.rsplit("/", 2)[0] + "/data/calib/front_kb_640x480.yaml")


@pytest.fixture(scope="module")
def sequences(tmp_path_factory):
    root = tmp_path_factory.mktemp("bench_eval")
    return [synth.write_sequence(root / name, CAM, synth.load_scenario(name), frames=10,
                                 flow=False, progress=False)
            for name in ("crossing", "highway", "overtaking", "preceding")]


@pytest.mark.benchmark(group="eval-4-sequences")
def test_eval_process_pool(benchmark, sequences):
    benchmark.pedantic(evaluate, args=(sequences, fm.Params()),
                       kwargs={"workers": 2, "progress": False}, rounds=3, iterations=1)


@pytest.mark.benchmark(group="eval-4-sequences")
def test_eval_dask_local_cluster(benchmark, sequences):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        evaluate(sequences[:2], fm.Params(), scheduler=cluster.scheduler_address,
                 progress=False)  # workers import and load their kernels once
        benchmark.pedantic(evaluate, args=(sequences, fm.Params()),
                           kwargs={"scheduler": cluster.scheduler_address, "progress": False},
                           rounds=3, iterations=1)


@pytest.mark.benchmark(group="eval-interleaved")
def test_eval_dask_interleaved_with_pool(benchmark, sequences):
    """The pool and the Dask cluster timed alternately in the same rounds (which goes first
    alternates too): their ratio without the drift between groups timed minutes apart
    (extra_info ``ratio``, Dask over pool, of the medians)."""
    distributed = pytest.importorskip("dask.distributed")
    times: dict[str, list[float]] = {"pool": [], "dask": []}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        runs = {"pool": {"workers": 2}, "dask": {"scheduler": cluster.scheduler_address}}
        evaluate(sequences[:2], fm.Params(), progress=False, **runs["dask"])  # workers warm
        order = ["pool", "dask"]

        def pair():
            for name in order:
                start = time.perf_counter()
                evaluate(sequences, fm.Params(), progress=False, **runs[name])
                times[name].append(time.perf_counter() - start)
            order.reverse()

        benchmark.pedantic(pair, rounds=6, iterations=1)
    pool_s, dask_s = (float(np.median(times[k])) for k in ("pool", "dask"))
    benchmark.extra_info.update(pool_s=round(pool_s, 3), dask_s=round(dask_s, 3),
                                ratio=round(dask_s / pool_s, 4))
