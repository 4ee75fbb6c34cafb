"""What a calibration writes: calibration.json and details.json as a set, the HTML report and
its figures, exports to other tools, and the tables printed on screen.
"""
