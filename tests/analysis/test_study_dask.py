"""``rig study`` on a Dask cluster, the saved study file and its use by ``rig design``.

A local 2-worker Dask cluster (separate processes, one thread each, on 127.0.0.1) must give the local
study's outcome scene by scene; the study file must round-trip; fits written to it must recover known
coefficients from outcomes drawn from Eq. 11 / Eq. 13 (binomial noise, a fixed seed).
Table II and the GCOR fit on noisy Eq. 11 rates are tested in ``test_design.py``.
"""

from __future__ import annotations

import itertools
import json
import math
import socket
from collections.abc import Iterator
from pathlib import Path

import distributed
import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from analysis import TABLE_I
from analysis.design import PAPER_GCOR, PAPER_SCOR, gcor, scor
from analysis.study import StudyResult, study
from analysis.study_dask import SCENE_FIELDS, ClusterError, record_blocks, study_dask, warm_up
from rig import study_file
from rig.cli import app
from rig.records import load_records
from rig.study_file import SCHEMA, StudyFileError, direction_array, read_study, write_study
from rig.study_summary import study_summary

pytestmark = pytest.mark.integration  # starts processes or opens sockets (tests/conftest.py)

runner = CliRunner()
ANGLES = np.radians([0.0, 2.0, 5.0])
BODIES = [TABLE_I[0], TABLE_I[3], TABLE_I[10]]


@pytest.fixture(scope="module")
def cluster() -> Iterator[distributed.LocalCluster]:
    """A local 2-worker cluster: processes, one thread each, loopback only, no dashboard."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as lc:
        yield lc


@pytest.fixture(scope="module")
def client(cluster: distributed.LocalCluster) -> Iterator[distributed.Client]:
    with distributed.Client(cluster, set_as_default=False) as c:
        yield c


@pytest.fixture(scope="module")
def records() -> list:
    return load_records("fema-farfield")[:10]


def assert_same_scenes(a: StudyResult, b: StudyResult) -> None:
    """Every per-scene array equal element by element (NaN equal to NaN)."""
    assert a.scenes == b.scenes
    for name in ("body", "record", "sign", "angle", *SCENE_FIELDS):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    assert a.records == b.records and a.signs == b.signs and a.cor() == b.cor()


# --------------------------------------------------------------------------------------------------
# The Dask study equals the local one


def test_record_blocks_cover_every_record_once() -> None:
    assert record_blocks(10, 3) == [(0, 3), (3, 7), (7, 10)]
    assert record_blocks(2, 8) == [(0, 1), (1, 2)]
    blocks = record_blocks(100, 8)
    assert blocks[0][0] == 0 and blocks[-1][1] == 100
    assert all(a[1] == b[0] for a, b in itertools.pairwise(blocks))


@pytest.mark.parametrize("blocks", [None, 3])
def test_dask_study_equals_local_scene_by_scene(client: distributed.Client, records: list,
                                                blocks: int | None) -> None:
    local = study(BODIES, records, ANGLES)
    remote = study_dask(BODIES, records, ANGLES, scheduler=client, blocks=blocks)
    assert remote.scenes == len(BODIES) * 10 * 2 * len(ANGLES)
    assert_same_scenes(local, remote)
    assert np.count_nonzero(remote.direction) > 0  # the comparison is not between two empty studies
    assert remote.settings["workers"] == 2 and remote.settings["where"].startswith("tcp://127.0.0.1:")
    assert remote.settings["blocks"] == (blocks or 8)


def test_warm_up_reaches_every_worker_with_its_thread_count(client: distributed.Client) -> None:
    assert warm_up(client) == dict.fromkeys(client.nthreads(), 1)


def test_dask_study_by_address_with_options(cluster: distributed.LocalCluster, records: list) -> None:
    kwargs = {"signs": (-1,), "restitution": "housner", "criterion": "static"}
    local = study(BODIES[:2], records[:5], ANGLES[1:], **kwargs)
    remote = study_dask(BODIES[:2], records[:5], ANGLES[1:], scheduler=cluster.scheduler_address, **kwargs)
    assert_same_scenes(local, remote)


def test_dask_study_general_model_equals_local(client: distributed.Client, records: list) -> None:
    local = study(BODIES[:2], records[:4], ANGLES, model="general", friction=0.6)
    remote = study_dask(BODIES[:2], records[:4], ANGLES, model="general", friction=0.6, scheduler=client)
    assert_same_scenes(local, remote)


def test_dask_study_refuses_bad_input_before_shipping(client: distributed.Client, records: list) -> None:
    with pytest.raises(ValueError, match="cannot stand"):
        study_dask([TABLE_I[0]], records[:1], [math.radians(15)], scheduler=client)


def test_unreachable_scheduler_is_named() -> None:
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ClusterError, match=f"tcp://127.0.0.1:{port}"):
        study_dask(BODIES[:1], load_records("fema-farfield")[:1], ANGLES[:1],
                   scheduler=f"tcp://127.0.0.1:{port}", timeout=1.0)


def test_cli_dask_equals_cli_local(cluster: distributed.LocalCluster, tmp_path: Path) -> None:
    args = ["study", "--records", "fema-farfield", "--bodies", "table1:1,4", "--angles", "0,3,5", "--json"]
    local = runner.invoke(app, [*args, "-o", str(tmp_path / "local.h5")])
    remote = runner.invoke(app, [*args, "-o", str(tmp_path / "dask.h5"), "--dask", cluster.scheduler_address])
    assert local.exit_code == 0, local.output
    assert remote.exit_code == 0, remote.output
    a, b = json.loads(local.stdout), json.loads(remote.stdout)
    assert a["where"] == "local" and b["where"] == cluster.scheduler_address
    for key in ("cor", "average_cor", "gcor", "scor", "scenes", "estimators", "gcor_paper", "scor_paper"):
        assert a[key] == b[key], key
    np.testing.assert_array_equal(read_study(tmp_path / "local.h5").direction,
                                  read_study(tmp_path / "dask.h5").direction)


def test_cli_dask_unreachable_exits_2(monkeypatch: pytest.MonkeyPatch) -> None:
    import analysis.study_dask as sd

    real = sd.study_dask
    monkeypatch.setattr(sd, "study_dask", lambda *a, **k: real(*a, **{**k, "timeout": 1.0}))
    result = runner.invoke(app, ["study", "--records", "fema-farfield:NORTHR/MUL009", "--bodies", "table1:1",
                                 "--angles", "0", "--dask", "tcp://127.0.0.1:9"])
    assert result.exit_code == 2
    assert "tcp://127.0.0.1:9" in result.output and "Traceback" not in result.output


# --------------------------------------------------------------------------------------------------
# The study file


@pytest.fixture(scope="module")
def small_study(records: list) -> StudyResult:
    return study(BODIES, records, np.radians([0, 1, 2, 3, 5, 7]))


def test_study_file_round_trips(small_study: StudyResult, tmp_path: Path) -> None:
    summary = study_summary(small_study)
    path = write_study(small_study, summary, tmp_path / "s.h5")
    saved = read_study(path)
    assert saved.attrs["schema"] == SCHEMA and saved.attrs["model"] == "rocking"
    assert saved.attrs["where"] == "local" and saved.attrs["scenes"] == small_study.scenes
    assert saved.records == small_study.records
    assert [(b.b, b.h, b.name) for b in saved.bodies] == [(b.b, b.h, b.name) for b in BODIES]
    np.testing.assert_allclose(saved.angles_rad, small_study.angles, rtol=1e-15)
    assert saved.direction.dtype == np.int8 and saved.direction.shape == (3, 10, 2, 6)
    np.testing.assert_array_equal(saved.direction, direction_array(small_study))
    # the direction array is the scene table reshaped: body, record, sign, angle
    i = 137
    j, r, s, m = np.unravel_index(i, saved.direction.shape)
    assert (small_study.body[i], small_study.record[i], small_study.angle[i]) == (j, r, small_study.angles[m])
    assert small_study.sign[i] == small_study.signs[s] and saved.direction[j, r, s, m] == small_study.direction[i]
    per_body = saved.cor[saved.cor["body_index"] >= 0]
    assert [(int(c["overturned"]), int(c["desired"])) for c in per_body] == \
        [(c["overturned"], c["desired"]) for c in saved.cor_from_direction()]
    assert [None if math.isnan(c) else c for c in per_body["cor"]] == [r["cor"] for r in summary["cor"]]
    average = saved.cor[saved.cor["body_index"] == -1]
    assert len(average) == 6 and list(average["overturned"]) == [r["overturned"] for r in summary["average_cor"]]
    assert saved.fits["gcor"]["c1"] == summary["gcor"]["c1"]
    assert [saved.fits["gcor"]["c1_ci_low"], saved.fits["gcor"]["c1_ci_high"]] == summary["gcor"]["c1_ci"]
    assert saved.fits["gcor"]["paper_c1"] == 0.048 and saved.fits["scor"]["paper_k1"] == 0.1136
    assert len(saved.estimators) == len(summary["estimators"]) >= 3 * 2
    assert set(saved.estimators["equation"]) <= {b"GCOR", b"SCOR"}
    assert saved.attrs["summary"]["scenes"] == small_study.scenes


def test_study_file_written_atomically(small_study: StudyResult, tmp_path: Path,
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    summary = study_summary(small_study)
    path = write_study(small_study, summary, tmp_path / "s.h5")
    before = path.read_bytes()

    def broken(h5: h5py.File, *args: object) -> None:
        h5.attrs["schema"] = "half written"
        raise OSError("disk full")

    monkeypatch.setattr(study_file, "_write_contents", broken)
    with pytest.raises(StudyFileError, match="disk full"):
        write_study(small_study, summary, path)
    assert path.read_bytes() == before  # the old file is untouched …
    assert [p.name for p in tmp_path.iterdir()] == ["s.h5"]  # … and no temporary file is left


def test_read_study_refuses_other_files(tmp_path: Path) -> None:
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as h5:
        h5.attrs["schema"] = "shaketable-rig/session/1"
    with pytest.raises(StudyFileError, match="schema"):
        read_study(other)
    with pytest.raises(StudyFileError, match="no such file"):
        read_study(tmp_path / "missing.h5")


@pytest.fixture(scope="module")
def saved_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``rig study … -o STUDY.h5`` (printed tables) on the 12 Table I bodies × 44 records × 2 signs × 7 angles."""
    path = tmp_path_factory.mktemp("study") / "study.h5"
    result = runner.invoke(app, ["study", "--records", "fema-farfield", "--bodies", "table1",
                                 "--angles", "0:6:1", "-o", str(path)])
    assert result.exit_code == 0, result.output
    for text in ("Controlled overturning rate", "SCOR (Eq. 13)", "GCOR (Eq. 11)", "Table III", "saved"):
        assert text in result.output, text
    return path


@pytest.mark.parametrize("equation", ["GCOR", "SCOR"])
def test_design_uses_the_study_files_fitted_equation(equation: str, saved_study: Path) -> None:
    path = saved_study
    coeffs = read_study(path).coefficients(equation)
    out = runner.invoke(app, ["design", "--body", "0.10x0.50", "--confidence", "0.9", "--equation", equation,
                              "--study", str(path), "--json"])
    assert out.exit_code == 0, out.output
    design = json.loads(out.stdout)
    assert design["source"] == "fitted"
    beta = design["angle_rad"]
    if equation == "GCOR":
        assert gcor(beta, *coeffs) == pytest.approx(0.9, abs=1e-9)
        assert coeffs != PAPER_GCOR
    else:
        assert scor(beta, (0.10, 0.50), coeffs[:3], coeffs[3]) == pytest.approx(0.9, abs=1e-9)
        assert coeffs[:3] != PAPER_SCOR


# --------------------------------------------------------------------------------------------------
# Fits written to the file recover the coefficients that generated the outcomes


def synthetic_study(rate: object, n_records: int = 100, seed: int = 11,
                    angles_deg: np.ndarray | None = None) -> StudyResult:
    """Every scene overturns; towards the low side (+1) with probability ``rate(body, beta)``."""
    angles = np.radians(np.arange(0.0, 7.01, 0.5) if angles_deg is None else angles_deg)
    bodies, signs = list(TABLE_I), (1, -1)
    nb, ns, na = len(bodies), len(signs), angles.size
    j, q, a = (x.ravel() for x in np.meshgrid(np.arange(nb), np.arange(n_records * ns), np.arange(na),
                                               indexing="ij"))
    p = np.array([[rate(body, beta) for beta in angles] for body in bodies])[j, a]
    direction = np.where(np.random.default_rng(seed).random(j.size) < p, 1, -1).astype(np.int8)
    n = j.size
    return StudyResult(bodies=bodies, records=[f"R{i}" for i in range(n_records)], angles=angles, signs=signs,
                       model="rocking", body=j, record=q // ns, sign=np.array(signs)[q % ns], angle=angles[a],
                       direction=direction, t_overturn=np.full(n, np.nan), theta_max=np.zeros(n),
                       impacts=np.zeros(n, dtype=np.int64), status=np.ones(n, dtype=np.int8),
                       steps=np.zeros(n, dtype=np.int64), prescreened=np.zeros(n, dtype=bool), seconds=0.0)


def test_gcor_fit_in_the_file_recovers_eq11_from_binomial_outcomes(tmp_path: Path) -> None:
    res = synthetic_study(lambda body, beta: float(gcor(beta)))
    saved = read_study(write_study(res, study_summary(res), tmp_path / "g.h5"))
    fit = saved.fits["gcor"]
    assert fit["c1_ci_low"] < 0.048 < fit["c1_ci_high"] and fit["c2_ci_low"] < 0.48 < fit["c2_ci_high"]
    assert fit["c1"] == pytest.approx(0.048, rel=0.1) and fit["c2"] == pytest.approx(0.48, rel=0.03)
    assert fit["eq12_error"] < 0.02  # 2400 outcomes per angle: the average is within ~1 pp of Eq. 11
    # Table III of the paper's GCOR against outcomes drawn from it: small for every body
    paper_gcor = saved.estimators[(saved.estimators["equation"] == b"GCOR")
                                  & (saved.estimators["coefficients"] == b"paper")]
    assert len(paper_gcor) == 12 and np.all(paper_gcor["error"] < 5)
    assert np.all(np.abs(paper_gcor["max_difference"]) < 12)
    assert paper_gcor["paper_error"][6] == 13  # body 7's printed value stands beside ours


def test_scor_fit_in_the_file_recovers_eq13_from_binomial_outcomes(tmp_path: Path) -> None:
    res = synthetic_study(lambda body, beta: float(scor(beta, body)), n_records=200)
    saved = read_study(write_study(res, study_summary(res), tmp_path / "s.h5"))
    fit = saved.fits["scor"]
    for name, true in zip(("k1", "k2", "k3"), PAPER_SCOR, strict=True):
        assert fit[f"{name}_ci_low"] < true < fit[f"{name}_ci_high"], name
    assert saved.coefficients("SCOR")[3] == 0.48 and math.isnan(fit["c2_ci_low"])
    assert fit["eq12_error"] < 0.02


def test_design_refuses_a_study_file_whose_fit_failed(tmp_path: Path) -> None:
    res = synthetic_study(lambda body, beta: float(gcor(beta)), n_records=5, angles_deg=np.array([0.0, 3.0]))
    path = write_study(res, study_summary(res), tmp_path / "two_angles.h5")
    assert "error" in read_study(path).fits["gcor"]  # two points cannot determine c1 and c2
    out = runner.invoke(app, ["design", "--body", "0.10x0.50", "--confidence", "0.9", "--equation", "GCOR",
                              "--study", str(path)])
    assert out.exit_code == 2
    assert "no fitted GCOR coefficients" in out.output and "Traceback" not in out.output
