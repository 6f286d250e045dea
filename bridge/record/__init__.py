"""Record a run's bus traffic (SENSOR and ACTION capture frames included) in any
python-can log format, and replay it against the firmware and the coordinator."""
