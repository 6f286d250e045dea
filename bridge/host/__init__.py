"""The host controller as its own process: the coordinator of
firmware_logic/behaviours/thesis/coordinator.py against a bus, with a SQLite (WAL) journal
written before every acknowledgement."""
