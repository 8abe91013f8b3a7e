"""The replay simulator and benchmark core: mazes, navigation graph, dynamics,
observations, renders and metrics. Pure numpy/scipy/opencv: no web, no torch, no database."""
