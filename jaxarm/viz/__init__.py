"""Pictures of a run folder: its figures (:mod:`jaxarm.viz.figures`, ``jaxarm figures``; the paper's among them,
:data:`jaxarm.paper.figures.FIGURES`) and a video of one
network reaching (:mod:`jaxarm.viz.video`, ``jaxarm video``). Both read only the files `jaxarm train`/`test` write
(``results.json``, ``trajectories.npz``, ``history.npz`` and, with ``--record-spikes``, ``spikes.npz`` and
``muscles.npz``); nothing is simulated again."""
