"""The tests (a package, so that pytest puts the repository on ``sys.path`` for ``tests/conftest.py``, not ``tests/``,
where ``tests/analysis`` and ``tests/rig`` would shadow the ``analysis`` and ``rig`` packages as namespace packages)."""
