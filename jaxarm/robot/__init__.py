"""The Barrett WAM side of the reproduction: our own MuJoCo model of the WAM, a libbarrett-like 500 Hz controller
behind a UDP receiver (the simulator, its own process), the exporter that streams joint trajectories to it, and the
tracking metrics and figures of the paper's §3.3 (Figs. 9-10).

Modules: :mod:`~jaxarm.robot.config` (every value and its source), :mod:`~jaxarm.robot.wam_model` (MJCF),
:mod:`~jaxarm.robot.protocol` (packets), :mod:`~jaxarm.robot.receiver` (the Network System),
:mod:`~jaxarm.robot.safety` (the safety envelope), :mod:`~jaxarm.robot.controller` (control chain and guards),
:mod:`~jaxarm.robot.simulator`, :mod:`~jaxarm.robot.exporter`, :mod:`~jaxarm.robot.rosbag` (ROS 2 bags),
:mod:`~jaxarm.robot.synthetic` (stand-in trajectory), :mod:`~jaxarm.robot.junk` (junk datagrams for robustness
tests), :mod:`~jaxarm.robot.metrics`, :mod:`~jaxarm.robot.figures`, :mod:`~jaxarm.robot.cli`. docs/robot.md is the
reference.
Nothing here imports the network; MuJoCo is imported only where the physics runs.
"""
