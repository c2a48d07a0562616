"""A mistyped --workers never grows into processes: the pool is never larger than
the runs to do, nor, without a Ray cluster's address, than the cores here; the
command line refuses more workers than cores in one line, before anything starts."""
import os

import pytest

from hpg_mj import cli
from hpg_mj.experiments import cores
from hpg_mj.experiments import runner


@pytest.mark.parametrize("requested, runs, address, expected", [
    (100000, 40, None, 2),          # the issue's --workers 100000: the 2 cores
    (None, 40, None, 2),            # default: one per core
    (8, 3, None, 2),
    (2, 1, None, 1),                # one run left: one process
    (None, 1, None, 1),
    (None, 0, None, 1),
    (100000, 40, "ray://head:10001", 40),   # a cluster: its CPUs bound it, the runs too
    (None, 40, "ray://head:10001", 40),
    (3, 40, "ray://head:10001", 3),
    (100000, None, None, 2),        # runs not known ahead: the cores
])
def test_the_pool_is_at_most_the_runs_and_the_cores(requested, runs, address, expected):
  assert cores.pool_size(requested, runs, address, here=2) == expected


def test_the_cores_are_those_this_process_may_use():
  if hasattr(os, "sched_getaffinity"):
    assert cores.available() == len(os.sched_getaffinity(0))
  assert 1 <= cores.available() <= os.cpu_count()
  for bad in (0, -3, True, 2.5, "4"):
    with pytest.raises(ValueError, match="workers must be a positive number of processes"):
      cores.pool_size(bad, 10)


def test_run_experiment_starts_no_more_processes_than_runs(tmp_path, monkeypatch):
  """fig6 --quick: 3 learners x its quick seeds; asked for 100000 workers."""
  started = []

  def fake_pool(todo, workers, *rest):
    started.append((len(todo), workers))
    raise KeyboardInterrupt        # nothing runs
  monkeypatch.setattr(runner, "_run_processes", fake_pool)
  monkeypatch.setattr(cores, "available", lambda: 100)
  experiment = runner.load_experiment("fig6")
  with pytest.raises(KeyboardInterrupt):
    runner.run_experiment(experiment, tmp_path, quick=True, workers=100000)
  (runs, workers), = started
  assert runs == len(runner.jobs(experiment, tmp_path, True)) and workers == min(runs, 100)
  monkeypatch.setattr(cores, "available", lambda: 2)
  with pytest.raises(KeyboardInterrupt):
    runner.run_experiment(experiment, tmp_path, quick=True, workers=100000)
  assert started[1] == (runs, 2)


@pytest.mark.parametrize("argv", [["run", "fig6", "--quick"], ["reproduce", "fig6", "--quick"],
                                  ["tune", "taxi_fuel_hpg"], ["bench", "experiments"]])
def test_more_workers_than_cores_are_refused_in_one_line(argv, tmp_path, capsys, monkeypatch):
  monkeypatch.setattr(cores, "available", lambda: 2)
  monkeypatch.chdir(tmp_path)
  with pytest.raises(SystemExit) as exit_:
    cli.main(argv + ["--workers", "100000"])
  assert exit_.value.code == 2
  err = capsys.readouterr().err
  cluster = ", or more on a Ray cluster (--executor ray --address ADDRESS)" \
      if argv[0] in ("run", "reproduce") else ""
  assert err == (f"hpg-mj {argv[0]}: error: --workers 100000 is more than the 2 cores this "
                 f"process may use; allowed: 1..2{cluster} (see hpg-mj {argv[0]} --help)\n")
  assert not list(tmp_path.iterdir())          # nothing was started or written


def test_a_ray_cluster_may_have_more_workers_than_the_cores_here():
  args = cli._parse(cli.build_parser(), ["run", "fig6", "--executor", "ray", "--address",
                                         "ray://head:10001", "--workers", "100000"])
  assert args.workers == 100000
