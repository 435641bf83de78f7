"""Drive compensation: the table's frequency response identified, and the drive iterated until the plate's achieved
acceleration reproduces the record, no play ever predicted to leave the table (``docs/compensation.md``,
``rig iterate``).

- ``signals``: commanded and measured accelerations per base axis and along the fall line, the error measures;
- ``identify``: the band-limited random identification drive and the per-axis H1 frequency response with coherence;
- ``mimo``: the response matrix (H1 with all axes excited at once, multiple coherence, condition number), its
  Tikhonov inverse, re-estimated play by play;
- ``laws``: the update laws, per axis (``diagonal``) and with the matrix (``mimo``);
- ``safety``: the plate's predicted response to a drive checked against Table IV and the legs, the level ramp;
- ``measures``: errors per axis and along the fall line, TRAC, response-spectrum error, peak against the limit;
- ``iteration``: the loop — ramp, predicted-response check, correction, roll-back;
- ``store``: the identification and the iterations in the session file (``/compensation``);
- ``table_play``: playing a drive on a table (any transport) as a run of the session;
- ``session``: one iteration session on a table (what ``rig iterate`` runs); the converged drive is saved with
  ``rig.drive.file`` (the drive file a sequence plays, ``drive = "FILE"``).
"""
