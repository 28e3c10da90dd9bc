"""``hairinv batch`` on a real Dask cluster: a LocalCluster, and a scheduler over TLS.

Two small grooms (3 guide strands of two samples) and one broken entry (a mesh given as the hair): the
broken one is reported with its message and the others finish; exit 1. The stage files are what
``hairinv invert`` makes (checked against the summary with h5py), and a second run reuses everything.

Runtime: about 30-60 s with a warm numba cache (each groom runs hairinv's commands in subprocesses).
"""

from __future__ import annotations

import json
import shutil
import subprocess

import h5py
import pytest

from conftest import SAMPLES, hairinv

MANIFEST = """
[defaults]
body = "body.obj"
guides = 3
exports = ["json"]
verify_seconds = 0.2

[[groom]]
name = "wavy"
hair = "wavy.h5"

[[groom]]
name = "straight"
hair = "straight.h5"
[groom.set]
"contacts.mu_body" = 0.2

[[groom]]
name = "broken"
hair = "body.obj"
"""


@pytest.fixture
def folder(tmp_path):
    for name in ("wavy.h5", "straight.h5", "body.obj"):
        shutil.copyfile(SAMPLES / name, tmp_path / name)
    (tmp_path / "grooms.toml").write_text(MANIFEST)
    return tmp_path


def test_a_batch_on_a_local_cluster_reports_every_groom_and_resumes(folder):
    first = hairinv(folder, "batch", "grooms.toml", "-o", "out", "--workers", "2")
    assert first.returncode == 1, first.stdout + first.stderr  # one groom failed
    summary = json.loads((folder / "out" / "batch.json").read_text())
    rows = {r["groom"]: r for r in summary["grooms"]}
    assert [r["groom"] for r in summary["grooms"]] == ["wavy", "straight", "broken"] and summary["failed"] == 1
    assert rows["broken"]["status"] == "failed" and "body.obj" in rows["broken"]["message"]
    assert "is it a mesh" in rows["broken"]["message"]
    for name in ("wavy", "straight"):
        row = rows[name]
        assert row["status"] == "ok" and row["verify"] == "PASS"
        with h5py.File(folder / "out" / f"{name}.model.h5", "r") as fh:
            assert row["strands"] == len(fh["helices/root"]) == 3
            assert row["contacts"] == len(fh["contacts/mu"]) and row["solver"] == fh["model"].attrs["status"]
            record = json.loads(fh.attrs["command"])
        assert (folder / "out" / f"{name}.json").exists() and (folder / "out" / f"{name}.log").exists()
        assert record["settings"]["import"]["guides"] == 3
    with h5py.File(folder / "out" / "straight.model.h5", "r") as fh:
        assert json.loads(fh["contacts"].attrs["config"])["contacts"]["mu_body"] == 0.2
    assert "groom" in first.stdout and "broken" in first.stdout  # the table
    second = hairinv(folder, "batch", "grooms.toml", "-o", "out")
    again = {r["groom"]: r for r in json.loads((folder / "out" / "batch.json").read_text())["grooms"]}
    assert second.returncode == 1
    for name in ("wavy", "straight"):
        assert again[name]["skipped"] == ["invert", "verify", "export json"]


def test_a_bad_manifest_is_refused_in_one_sentence(folder):
    (folder / "bad.toml").write_text('[[groom]]\nname = "x"\nhair = "wavy.h5"\ncolour = "red"\n')
    result = hairinv(folder, "batch", "bad.toml")
    assert result.returncode == 2 and "bad.toml" in result.stderr and "colour" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (folder / "batch").exists()


SHOTS = """
[[groom]]
name = "straight"
hair = "straight.h5"
body = "turn.glb"
guides = 3
stages = ["invert"]

[[shot]]
name = "turn"
groom = "straight"
body = "turn.glb"
seconds = 0.2
exports = ["json"]

[[shot]]
name = "start"
groom = "straight"
body = "turn.glb"
seconds = 0.1
fps = 20
"""


def test_shots_of_a_groom_run_once_its_model_is_made_and_resume(folder):
    shutil.copyfile(SAMPLES / "turn.glb", folder / "turn.glb")
    (folder / "shots.toml").write_text(SHOTS)
    first = hairinv(folder, "batch", "shots.toml", "-o", "out", "--workers", "2")
    assert first.returncode == 0, first.stdout + first.stderr
    summary = json.loads((folder / "out" / "batch.json").read_text())
    rows = {r["groom"]: r for r in summary["grooms"]}
    assert list(rows) == ["straight", "turn", "start"] and summary["failed"] == 0
    for name, seconds, fps in (("turn", 0.2, None), ("start", 0.1, 20.0)):
        assert rows[name]["status"] == "ok" and rows[name]["shot_of"] == "straight"
        with h5py.File(folder / "out" / f"{name}.frames.h5", "r") as fh:
            frames = fh["frames"]
            assert frames.attrs["body_animated"] and len(frames["binding_triangle"]) == 3
            assert frames["time"][-1] == pytest.approx(seconds)
            if fps is not None:
                assert frames.attrs["fps"] == fps
            assert rows[name]["solver"] == f"{len(frames['time'])} frames"
            record = json.loads(fh.attrs["command"])
        assert record["inputs"][0]["name"] == "straight.model.h5" and record["inputs"][1]["name"] == "turn.glb"
    assert (folder / "out" / "turn.json").exists() and not (folder / "out" / "start.json").exists()
    second = hairinv(folder, "batch", "shots.toml", "-o", "out")
    again = {r["groom"]: r for r in json.loads((folder / "out" / "batch.json").read_text())["grooms"]}
    assert second.returncode == 0
    assert again["turn"]["skipped"] == ["simulate", "export json"] and again["start"]["skipped"] == ["simulate"]


def test_a_shot_of_a_groom_the_manifest_does_not_list_is_refused(folder):
    (folder / "bad.toml").write_text('[[groom]]\nname = "x"\nhair = "wavy.h5"\n\n'
                                     '[[shot]]\nname = "s"\ngroom = "y"\nbody = "body.obj"\n')
    result = hairinv(folder, "batch", "bad.toml")
    assert result.returncode == 2 and "bad.toml" in result.stderr and "'y'" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (folder / "batch").exists()


def _certificate(folder):
    """A self-signed certificate, its own CA, for the scheduler, the workers and the client."""
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "key.pem", "-out",
                    "cert.pem", "-days", "1", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1"],
                   cwd=folder, check=True, capture_output=True)
    return folder / "cert.pem", folder / "key.pem"


def test_a_batch_on_a_tls_scheduler(folder):
    pytest.importorskip("distributed")
    if shutil.which("openssl") is None:
        pytest.skip("openssl not found: no certificate to test TLS with")
    from distributed import LocalCluster
    from distributed.security import Security

    cert, key = _certificate(folder)
    security = Security(tls_ca_file=str(cert), tls_scheduler_cert=str(cert), tls_scheduler_key=str(key),
                        tls_worker_cert=str(cert), tls_worker_key=str(key), tls_client_cert=str(cert),
                        tls_client_key=str(key), require_encryption=True)
    (folder / "one.toml").write_text('[[groom]]\nname = "wavy"\nhair = "wavy.h5"\nbody = "body.obj"\nguides = 3\n'
                                     'stages = ["invert"]\n')
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tls://", host="127.0.0.1",
                      security=security, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tls://")
        plain = hairinv(folder, "batch", "one.toml", "--scheduler", address, "-o", "plain")
        assert plain.returncode == 2 and "could not connect" in plain.stderr and "--tls-ca-file" in plain.stderr
        result = hairinv(folder, "batch", "one.toml", "--scheduler", address, "--tls-ca-file", cert,
                         "--tls-cert", cert, "--tls-key", key, "-o", "secure")
        assert result.returncode == 0, result.stdout + result.stderr
    row = json.loads((folder / "secure" / "batch.json").read_text())["grooms"][0]
    assert row["status"] == "ok" and row["strands"] == 3
