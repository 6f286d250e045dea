"""Host-side incremental perception (issue 13): an evidence grid built from
touches and robot poses, a shape estimate with its uncertainty, and
recognition against a shape library. numpy is fine here; nothing in
firmware_logic imports this package (docs/perception.md).
"""
