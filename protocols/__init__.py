"""Wire formats only: the MAVLink dialect, CANopen object and PDO maps, zenoh keys and payloads.

Imports nothing of ours. Populated by the transports issue.
"""
