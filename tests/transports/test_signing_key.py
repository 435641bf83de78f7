"""The rig's signing key (protocols/signing_key.py): read from a key file or the environment, refused when the file
is open to other users or the key cannot be random, written new readable by its owner only (issue 42, item 6)."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

import pytest
import typer

from protocols.signing_key import KEY_ENV, SigningKeyError, key_from_passphrase, load_signing_key, write_signing_key

KEY = bytes.fromhex("d31206b30393bd1c639b2d588f463d4518c16a9a1d39a506bfefb510bc70d4e3")  # secrets.token_hex(32)


def key_file(path: Path, content: bytes, mode: int = 0o600) -> Path:
    path.write_bytes(content)
    path.chmod(mode)
    return path


def test_signing_key_from_file_or_environment(tmp_path: Path) -> None:
    raw = key_file(tmp_path / "raw.key", b"\n" + KEY[1:])  # 32 raw bytes, whitespace included, are raw
    assert load_signing_key(raw, env={}) == b"\n" + KEY[1:]
    hexa = key_file(tmp_path / "hex.key", KEY.hex().upper().encode() + b"\n")
    assert load_signing_key(str(hexa), env={}) == KEY
    assert load_signing_key(env={KEY_ENV: f"  {KEY.hex()} "}) == KEY
    assert load_signing_key(hexa, env={KEY_ENV: "00" * 32}) == KEY  # a file given wins
    assert load_signing_key(key_file(tmp_path / "read-only.key", KEY.hex().encode(), 0o400), env={}) == KEY


@pytest.mark.parametrize("mode", [0o644, 0o666, 0o640, 0o604, 0o610])
def test_a_key_file_other_users_may_read_is_refused_with_the_chmod_to_run(tmp_path: Path, mode: int) -> None:
    path = key_file(tmp_path / "rig.key", KEY.hex().encode() + b"\n", mode)
    with pytest.raises(SigningKeyError) as err:
        load_signing_key(path, env={})
    assert str(err.value) == (f"signing key file {path}: mode {mode:04o} lets other users read the rig's key; run: "
                              f"chmod 600 {path}")


@pytest.mark.parametrize(("content", "env", "why"), [
    (None, {}, "no MAVLink signing key: set SHAKETABLE_MAVLINK_KEY"),
    (None, {KEY_ENV: "ab" * 16}, "SHAKETABLE_MAVLINK_KEY: expected 64 hexadecimal digits, got 32"),
    (None, {KEY_ENV: "zz" * 32}, "SHAKETABLE_MAVLINK_KEY: not hexadecimal"),
    (None, {KEY_ENV: "00" * 32}, "all-zero key"),
    (None, {KEY_ENV: "00" * 31 + "01"}, "too little entropy"),
    (None, {KEY_ENV: "ab" * 32}, "too little entropy"),
    (None, {KEY_ENV: "0123456789abcdef" * 4}, "too little entropy"),
    (None, {KEY_ENV: bytes(range(1, 33)).hex()}, "too little entropy"),  # 32 distinct bytes, counting
    (b"\x00" * 32, {}, "all-zero key"),
    (b"\x00" * 31 + b"\x01", {}, "too little entropy"),
    (("00" * 31 + "01\n").encode(), {}, "too little entropy"),
    (b"correct horse battery staple 42", {}, "expected 64 hexadecimal digits, got 31"),
    (b"correct horse battery staple 42!", {}, "32 printable characters: a password or half a hexadecimal key"),
    (KEY.hex()[:32].encode(), {}, "32 printable characters"),
    (b"\xff" * 31, {}, "31 bytes, neither 32 raw bytes nor 64 hexadecimal digits"),
    (b"ab" * 31 + b"\n", {}, "expected 64 hexadecimal digits, got 62"),
    ("missing", {}, "No such file"),
])
def test_a_bad_signing_key_is_refused_with_its_source(tmp_path: Path, content: bytes | str | None,
                                                      env: dict[str, str], why: str) -> None:
    path = None
    if content == "missing":
        path = tmp_path / "missing.key"
    elif isinstance(content, bytes):
        path = key_file(tmp_path / "bad.key", content)
    with pytest.raises(SigningKeyError, match=why) as err:
        load_signing_key(path, env=env)
    assert "\n" not in str(err.value)
    assert (str(path) if path is not None else KEY_ENV) in str(err.value)


def test_a_random_key_passes_the_entropy_check() -> None:
    for _ in range(2000):  # refused with probability < 1e-15 each
        key = os.urandom(32)
        assert load_signing_key(env={KEY_ENV: key.hex()}) == key


def test_a_written_key_is_random_owner_only_and_never_overwrites(tmp_path: Path) -> None:
    path = tmp_path / "new.key"
    key = write_signing_key(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_signing_key(path, env={}) == key
    assert write_signing_key(tmp_path / "other.key") != key
    with pytest.raises(FileExistsError):
        write_signing_key(path)
    assert load_signing_key(path, env={}) == key


def test_a_passphrase_gives_the_sha256_key_of_ardupilot_s_tools() -> None:
    # the SHA-256 of "correct horse battery staple", a widely published test vector (not computed by the code tested)
    assert key_from_passphrase("correct horse battery staple").hex() == \
        "c4bbcb1fbec99d65bf59d85c8cb62ee2db963f0fe106f483d9afa73bd4e39a8a"


@pytest.mark.parametrize(("passphrase", "expected"), [
    ("tablekey", r"too weak \(8 characters, 7 distinct\): a passphrase has at least 20 characters"),
    ("aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa", r"34 characters, 1 distinct"),
    ("überlange Passphrase für den Tisch", "printable ASCII"),
])
def test_a_weak_passphrase_is_refused_saying_what_it_must_be(passphrase: str, expected: str) -> None:
    with pytest.raises(SigningKeyError, match=expected) as raised:
        key_from_passphrase(passphrase)
    assert str(raised.value).startswith("--key-passphrase: ")


def test_key_passphrase_on_the_command_line(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from rig.cli import app
    from rig.console import operator_token

    monkeypatch.delenv(KEY_ENV, raising=False)  # the command sets it in this process: restored after the test
    passphrase = "correct horse battery staple"
    given = CliRunner().invoke(app, ["service", "token", "--key-passphrase", passphrase])
    assert given.exit_code == 0, given.output
    assert given.stdout.strip() == operator_token(key_from_passphrase(passphrase))
    monkeypatch.setenv("SHAKETABLE_KEY_PASSPHRASE", passphrase)
    assert CliRunner().invoke(app, ["service", "token"]).stdout.strip() == given.stdout.strip()
    both = CliRunner().invoke(app, ["service", "token", "--key-passphrase", passphrase, "--key-file",
                                    str(key_file(tmp_path / "k", KEY.hex().encode()))])
    assert both.exit_code == 2 and "give the rig's key one way" in both.output
    weak = CliRunner().invoke(app, ["service", "token", "--key-passphrase", "tablekey"])
    assert weak.exit_code == 2 and "too weak" in weak.output


def _commands(group: Any, prefix: str = "rig") -> list[tuple[str, Any]]:
    """Every command under the command group ``group``, with its full name."""
    found: list[tuple[str, Any]] = []
    for name, command in group.commands.items():
        if hasattr(command, "commands"):
            found += _commands(command, f"{prefix} {name}")
        else:
            found.append((f"{prefix} {name}", command))
    return found


def test_every_command_with_key_file_takes_key_passphrase() -> None:
    import typer.main

    from rig.cli import app

    commands = _commands(typer.main.get_command(app))
    with_key = [name for name, command in commands
                if any("--key-file" in param.opts for param in command.params)]
    without = [name for name, command in commands if name in with_key and not any(
        "--key-passphrase" in param.opts for param in command.params)]
    assert {"rig run", "rig serve", "rig table list", "rig table check", "rig console"} <= set(with_key)
    assert without == []


def test_rig_emulate_passes_the_passphrase_on_as_the_key(monkeypatch: pytest.MonkeyPatch) -> None:
    """``rig emulate`` hands its options to ``python -m sim_table``: ``--key-passphrase`` is taken out of them and
    its key put where the emulator reads the rig's key."""
    from rig.cli.emulate import take_key_passphrase

    monkeypatch.delenv(KEY_ENV, raising=False)
    monkeypatch.delenv("SHAKETABLE_KEY_PASSPHRASE", raising=False)
    passphrase = "correct horse battery staple"
    rest = take_key_passphrase(["--listen", "mavlink://127.0.0.1:14600", "--key-passphrase", passphrase,
                                "--replay-state", "r.json"])
    assert rest == ["--listen", "mavlink://127.0.0.1:14600", "--replay-state", "r.json"]
    assert os.environ[KEY_ENV] == key_from_passphrase(passphrase).hex()
    assert take_key_passphrase([f"--key-passphrase={passphrase}"]) == []
    monkeypatch.delenv(KEY_ENV)
    assert take_key_passphrase(["--listen", "x"]) == ["--listen", "x"] and KEY_ENV not in os.environ
    with pytest.raises(typer.Exit):
        take_key_passphrase(["--key-passphrase", passphrase, "--key-file", "rig.key"])
    with pytest.raises(typer.Exit):
        take_key_passphrase(["--key-passphrase"])


def test_rig_table_list_refuses_a_weak_passphrase_before_any_link() -> None:
    from typer.testing import CliRunner

    from rig.cli import app

    weak = CliRunner().invoke(app, ["table", "list", "--connect", "tls/10.231.0.2:7447", "--key-passphrase",
                                    "tablekey"])
    assert weak.exit_code == 2 and "too weak" in weak.output, weak.output
