"""The RSP paper's experiments (§IV, Figs. 10 and 11) on a simulated clock.

- `simulation`: the clock, a path (a bottleneck link and an `impair.ImpairedChannel`) per
  direction, and `RspSimulation`, a `LocalEndpoint` and a `RobotEndpoint` with a simulated CUBO.
- `tcp`: the baseline of Fig. 11, fixed-size packets over a model of TCP in simulated time.
- `packet_size`: experiment 1, the variable packet size (Fig. 10).
- `path_following`: experiment 2, path following under delay and loss (Fig. 11): its settings,
  a lap over each transport and the sweep; `path_reference` the path it follows,
  `path_controller` the local system's pure pursuit, `path_run` one run and its path error,
  `path_report` its Markdown report.
- `plots`: the figures (matplotlib, imported only there and only when drawing).
"""
