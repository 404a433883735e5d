"""The evaluation of four rendered sequences in a local process pool and on a Dask LocalCluster
(two workers each, one thread, workers' glibc malloc thresholds restored by the job)."""

from __future__ import annotations

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
