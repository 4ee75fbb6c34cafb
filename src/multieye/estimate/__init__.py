"""From measurements to estimates: pairing in time, consensus, clock offsets, the image-level
refinement problem, uncertainty and motion diagnostics.
"""
