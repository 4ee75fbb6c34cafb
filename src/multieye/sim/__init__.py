"""Synthetic rigs, noise, rendered images and the demo dataset.

Imported only by ``multieye.sim`` itself, the experiments, the demo and the command line;
production code never depends on it.
"""
