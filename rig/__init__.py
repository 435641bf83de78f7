"""The lab application: records → drive → run orchestration → run logs; the ``rig`` CLI."""

__version__ = "0.1.0"
