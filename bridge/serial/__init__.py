"""Serial links and serial robot bodies.

- transport.py: SerialTransport, framed messages (firmware_logic/framing.py)
  over any pyserial port or URL; the host process uses it per robot port.
- pty.py: pseudo-terminal helpers (a program behind a pty, with faults).
- khepera.py / gogo.py: HAL drivers for Khepera II and GoGo Board robots.
"""
