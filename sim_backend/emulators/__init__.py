"""Device-side stand-ins fed by the sim world.

- tether.py: the body server of a tethered MicroPython robot (answers its
  SENSOR queries from the world, applies its ACTIONs).
- khepera.py / gogo.py: Khepera II and GoGo Board emulators on a pty,
  written from the protocol description (docs/serial.md), not from the
  drivers in bridge/serial.
- ptyport.py: the pty they answer on.
"""
