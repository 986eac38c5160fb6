"""The SUMO closed loop (the ``[sim]`` extra): traffic, the ego controller that re-plans every period
with a registry planner, episodes, campaigns on Dask, metrics and figures.

Nothing here imports SUMO on import: :func:`iamp.simulation.network.require_sumo` says which extra
to install when an episode starts.  Modules: ``planning`` (the planners of the loop),
``controller``, ``episode``, ``simulator``, ``network``, ``traffic``, ``metrics``, ``campaign``,
``figures``.
"""
