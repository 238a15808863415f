"""The paper's layer: what reproduces Dura-Bernal et al. 2015 in particular, above the framework.

* :mod:`jaxarm.paper.reproduce`: ``jaxarm reproduce``, the success table (counts, reach measures, jerk) beside the
  paper's, each arm's default protocol;
* :mod:`jaxarm.paper.presets`: the named metaparameter sets of the project's searches (the README's in the package
  folder, the rest in ``archive/``);
* :mod:`jaxarm.paper.comparison`: the paper's reported values and the original NEURON model's reference runs
  (``data/``), and our run folders' statistics beside them.

The framework below (config, arm, network, learning, task, loop, train, run, evolve, robot, analysis) imports
nothing from here.
"""
