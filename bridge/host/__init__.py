"""The host controller as its own process: any behaviour's coordinator (the
host contract, firmware_logic/roster.py) against a bus, with a SQLite (WAL)
journal written before every acknowledgement."""
