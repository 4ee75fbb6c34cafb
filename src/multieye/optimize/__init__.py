"""The one optimisation engine under every refinement: parameter blocks on manifolds, robust
loss, Levenberg-Marquardt on the normal equations with the per-measurement blocks eliminated
by a Schur complement, and the covariance from the same factorisation.
"""
