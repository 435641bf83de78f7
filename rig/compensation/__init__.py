"""Drive compensation: the table's frequency response identified, and the drive iterated until the plate's achieved
acceleration reproduces the record (``docs/table-dynamics.md``, ``rig iterate``).

- ``signals``: commanded and measured accelerations per base axis and along the fall line, the error measures;
- ``identify``: the band-limited random identification drive and the H1 frequency response with coherence;
- ``iteration``: the correction with the regularised inverse response, relaxation and the limits re-checked;
- ``store``: the identification and the iterations in the session file (``/compensation``);
- ``table_play``: playing a drive on a table (any transport) as a run of the session;
- ``session``: one iteration session on a table (what ``rig iterate`` runs); the converged drive is saved with
  ``rig.drive.file`` (the drive file a sequence plays, ``drive = "FILE"``).
"""
