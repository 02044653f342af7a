"""The sweep plugin: one graph over many missions, seeds and parameter variants, on Dask distributed.

    from impala_sweep.spec import load_sweep
    from impala_sweep.runner import run_sweep

    spec = load_sweep("graphs/sweeps/rslam-search.yaml")   # the sweep file, validated, located
    outcome = run_sweep(spec, "out/sweep")                  # a LocalCluster; scheduler="tcp://..." for a cluster

Modules: :mod:`.spec` (the sweep file), :mod:`.check` (checks on the client), :mod:`.folder`
(the sweep's folder), :mod:`.task` (one task, run on a worker), :mod:`.results` (results.csv,
summary.md, variants.png), :mod:`.runner` (Dask), :mod:`.command` (``impala-flow sweep``),
:mod:`.plugin` (the entry point). It uses only impala-flow's public API; only :mod:`.runner`
and :mod:`.command` import ``distributed``, and only when a sweep runs.
"""
