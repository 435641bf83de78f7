"""``rig run`` with a key file it must refuse (issue 42, item 6): one line naming the file and the chmod to run,
before an emulator is started or a table contacted."""

from __future__ import annotations

import secrets
from pathlib import Path

import pytest

from rig.orchestrator.setup import TableUnreachableError, table_for
from rig.sequence import load_sequence

QUICK = Path(__file__).resolve().parents[2] / "examples" / "quick.toml"


@pytest.mark.parametrize("emulate", [True, False])
def test_a_key_file_others_can_read_is_refused_before_anything_starts(tmp_path: Path, emulate: bool) -> None:
    key = tmp_path / "rig.key"
    key.write_text(secrets.token_hex(32) + "\n")
    key.chmod(0o644)
    sequence = load_sequence(QUICK)
    with pytest.raises(TableUnreachableError) as err, \
            table_for(sequence, None if emulate else "mavlink://127.0.0.1:9", emulate, key, 1.0):
        pytest.fail("the table was used")
    assert str(err.value) == (f"the table was not contacted: signing key file {key}: mode 0644 lets other users "
                              f"read the rig's key; run: chmod 600 {key}")
