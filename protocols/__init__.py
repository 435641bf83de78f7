"""Wire formats only: the MAVLink dialect, CANopen object and PDO maps, zenoh keys and payloads.

Imports nothing of ours. Populated by the transports issue.

- ``protocols.mavlink``: the MAVLink 2 dialect ``shaketable.xml`` (Python generated with pymavlink's mavgen on
  first use, cached per user, never committed), setpoint/accelerometer framing, signing, UDP links.
"""
