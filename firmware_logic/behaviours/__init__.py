"""Behaviours: each a package of firmware-subset modules (the robot FSM and
its declaration, spec.py) plus its host-side coordinator. The registry that
finds them by name or path is host code (CPython only) in
sim_backend/registry.py."""
