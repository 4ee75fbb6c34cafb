"""Foundations every layer uses: errors, frames and Lie maths, robust losses, lens models,
metrics and the problem description (setups, measurement groups).

Nothing here imports another subpackage of multieye.
"""
