"""Monte Carlo sweeps (``multieye experiment``) on simulated rigs, with their CSV and figures.
"""
