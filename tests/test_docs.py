"""The documents in docs/ are the contract: they exist, nothing points outside the repository
for them, and they name every key that rig.yaml accepts and that the outputs hold."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from multieye.core import geometry
from multieye.core.intrinsics import Intrinsics
from multieye.core.lens_curve import RadialCurve
from multieye.estimate.diagnostics import CameraMotion
from multieye.io import rig as rig_yaml
from multieye.io.calibration_json import (
    SETUP_KEYS,
    CalibrationRecord,
    CameraRecord,
    IntrinsicsRecord,
    PlausibilityItem,
    PoseUncertainty,
    RejectedItem,
    Residuals,
    calibration_to_dict,
)
from multieye.io.mocap_csv import DEFAULT_COLUMNS
from multieye.io.rig_targets import TARGETS_ENTRY_KEYS
from multieye.io.run_details import (
    CameraDetails,
    RunDetails,
    TrajectoryDetails,
    run_details_to_dict,
)
from multieye.outputs.export import FORMATS
from multieye.outputs.report import FIGURES

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"

#: Files that still name DESIGN.md because they are being rewritten by someone else.  Each
#: entry must still name it (a stale entry fails too), so the set only shrinks.

_TEXT_SUFFIXES = {".py", ".md", ".txt", ".toml", ".yaml", ".cfg", ".typed"}


def _files(*roots: str) -> list[Path]:
    """Text files under the given repository paths (build and cache folders left out)."""
    out = []
    for root in roots:
        path = REPO / root
        if path.is_file():
            out.append(path)
            continue
        for p in sorted(path.rglob("*")):
            parts = p.relative_to(REPO).parts
            if (p.is_file() and p.suffix in _TEXT_SUFFIXES
                    and not any(s.endswith(".egg-info") or s == "__pycache__" for s in parts)):
                out.append(p)
    return out


def _rel(p: Path) -> str:
    return p.relative_to(REPO).as_posix()


def _sections(name: str) -> dict[int, str]:
    """``## N. Title`` sections of a document: number -> text (title line included)."""
    parts = re.split(r"^## (\d+)\. ", (DOCS / name).read_text(), flags=re.M)
    return {int(n): body for n, body in zip(parts[1::2], parts[2::2])}


def _tables(section: str, header: str) -> list[dict[str, str]]:
    """Tables of a section whose header row is ``header``: first cell's `name` -> row."""
    tables, current = [], None
    for line in section.splitlines():
        if line.strip() == header:
            current = {}
            tables.append(current)
        elif current is not None and line.startswith("|"):
            m = re.match(r"^\| `([^`]+)` \|", line)
            if m:
                current[m.group(1)] = line
        else:
            current = None
    return tables


def _named(section: str, key: str) -> bool:
    return f"`{key}`" in section


# --------------------------------------------------------------------------- (a), (b)


def test_nothing_names_design_md():
    found = {_rel(p) for p in _files("src", "README.md", "tests", "benchmarks", "docs")
             if "DESIGN.md" in p.read_text(errors="replace")}
    found.discard(_rel(Path(__file__)))
    assert found == set(), (
        "DESIGN.md is not in the repository; point to docs/conventions.md, docs/rig-yaml.md "
        "or docs/outputs.md (with the section) instead")


def test_every_named_document_exists():
    missing = []
    for p in _files("src", "README.md", "tests", "benchmarks", "docs"):
        for doc in set(re.findall(r"docs/[A-Za-z0-9_./-]*[A-Za-z0-9_-]\.md", p.read_text())):
            if not (REPO / doc).is_file():
                missing.append(f"{_rel(p)}: {doc}")
    assert missing == []


def test_every_named_section_exists():
    """``docs/conventions.md, section 2`` (and ``sections 2 and 6``) name real sections."""
    wrong = []
    pattern = re.compile(r"(docs/[\w-]+\.md),?\s+sections?\s+(\d+)(?:\s+and\s+(\d+))?")
    for p in _files("src", "README.md", "tests", "benchmarks", "docs"):
        for doc, *numbers in pattern.findall(p.read_text()):
            if not (REPO / doc).is_file():
                continue  # reported by test_every_named_document_exists
            have = _sections(Path(doc).name)
            wrong += [f"{_rel(p)}: {doc} section {n}" for n in numbers
                      if n and int(n) not in have]
    assert wrong == []


def test_markdown_links_stay_inside_the_repository():
    broken = []
    for p in [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]:
        for target in re.findall(r"\]\(([^)\s#]+)(?:#[^)]*)?\)", p.read_text()):
            if re.match(r"[a-z]+://", target):
                continue
            resolved = (p.parent / target).resolve()
            if not resolved.exists() or REPO not in resolved.parents:
                broken.append(f"{_rel(p)}: {target}")
    assert broken == []


def test_the_readme_links_the_three_documents():
    text = (REPO / "README.md").read_text()
    for name in ("conventions.md", "rig-yaml.md", "outputs.md"):
        assert f"(docs/{name})" in text


# --------------------------------------------------------------------------- (c) rig.yaml

RIG_HEADER = "| key | type | default | meaning |"


def test_rig_yaml_doc_names_exactly_the_keys_the_loader_accepts():
    s = _sections("rig-yaml.md")
    expected = [(2, [rig_yaml.TOP_LEVEL_KEYS]),
                (3, [rig_yaml.TARGET_KEYS, TARGETS_ENTRY_KEYS]),
                (4, [rig_yaml.MOCAP_KEYS]),
                (5, [rig_yaml.CAMERA_KEYS, rig_yaml.CAMERA_INTRINSICS_KEYS])]
    for number, key_sets in expected:
        tables = _tables(s[number], RIG_HEADER)
        assert [set(t) for t in tables] == [set(k) for k in key_sets], f"section {number}"


def test_rig_yaml_doc_lists_the_csv_column_names():
    section = _sections("rig-yaml.md")[4]
    roles = {}
    for line in section[section.index("| role | names |"):].splitlines():
        m = re.match(r"^\| `(\w+)` \| (`.*)\|$", line)
        if m:
            roles[m.group(1)] = re.findall(r"`([^`]+)`", m.group(2))
    assert set(rig_yaml.MOCAP_COLUMN_KEYS) <= set(roles)
    for role in rig_yaml.MOCAP_COLUMN_KEYS:
        assert roles[role] == list(DEFAULT_COLUMNS[role]), role


def test_rig_yaml_defaults_are_the_loaders(tmp_path):
    (tmp_path / "mocap.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "cam0.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-to-base\nmocap: {file: mocap.txt}\ncameras:\n  cam0: {poses: cam0.txt}\n")
    rig = rig_yaml.load_rig(tmp_path)
    s = _sections("rig-yaml.md")
    mocap = _tables(s[4], RIG_HEADER)[0]
    camera = _tables(s[5], RIG_HEADER)[0]
    assert f"`{rig.mocap.time_tolerance:g}`" in mocap["time_tolerance"]
    assert f"`{rig.mocap.duplicates}`" in mocap["duplicates"].split("|")[3]
    assert f"`{rig.mocap.pose}` (eye-to-base)" in mocap["pose"]
    assert rig.mocap.rot_sigma_rad is None and "estimated" in mocap["rotation_noise_deg"]
    assert rig.mocap.trans_sigma_m is None and "estimated" in mocap["translation_noise_m"]
    assert f"`{rig.cameras['cam0'].time_offset}`" in camera["time_offset"]
    (tmp_path / "rig.yaml").write_text(
        "setup: eye-on-hand\nmocap: {file: mocap.txt}\ncameras:\n  cam0: {poses: cam0.txt}\n")
    assert f"`{rig_yaml.load_rig(tmp_path).mocap.pose}` (eye-on-hand)" in mocap["pose"]


def test_planned_keys_are_not_accepted_yet():
    """When the loader starts accepting a planned key, move it to its section."""
    planned = _tables(_sections("rig-yaml.md")[7], "| key | where | planned meaning |")[0]
    accepted = set().union(rig_yaml.TOP_LEVEL_KEYS, rig_yaml.TARGET_KEYS, rig_yaml.MOCAP_KEYS,
                           rig_yaml.CAMERA_KEYS, rig_yaml.CAMERA_INTRINSICS_KEYS)
    plain = {k for k in planned if re.fullmatch(r"\w+", k)}
    assert {"diameter", "legacy"} <= plain
    assert plain & accepted == set()
    types = {k.split(": ")[1] for k in planned if k.startswith("type: ")}
    assert types.isdisjoint(rig_yaml.TARGET_TYPES)


# --------------------------------------------------------------------------- (d) outputs


def _record(setup: str) -> CalibrationRecord:
    """A record with every optional field set."""
    rng = np.random.default_rng(5)
    X = geometry.random_transforms(rng, 2)
    A = rng.normal(size=(6, 6))
    x_key = SETUP_KEYS[setup][1]
    unc = PoseUncertainty(0.02, 4e-4, A @ A.T * 1e-8)
    lens = Intrinsics(K=[[600, 0, 320], [0, 600, 240], [0, 0, 1]], dist=np.zeros(5),
                      width=640, height=480)
    cams = [CameraRecord(f"cam{j}", X[j], geometry.inv(X[0]) @ X[j], 30,
                         residuals=Residuals(0.01, 1e-4, 0.05, 3e-4, 0.2), time_offset_s=0.01,
                         time_offset_std_s=1e-4, std_rot_deg=0.02, std_trans_m=4e-4, covariance=A @ A.T * 1e-8,
                         rejected=(RejectedItem("1700000000.5.png", "no target detected"),),
                         intrinsics=IntrinsicsRecord(lens, True, np.eye(9), (0.1, 0.3),
                                                     RadialCurve(np.ones(3), np.ones(3),
                                                                 np.eye(3))),
                         uncertainty={x_key: unc, "T_ref_cam": unc})
            for j in range(2)]
    motion = {c.name: CameraMotion(c.name, 30, 60.0, np.array([20.0, 10.0, 5.0]), 3.0,
                                   float("inf")).as_dict() for c in cams}
    return CalibrationRecord(setup, "joint", "cam0", geometry.random_transforms(rng), cams,
                             Residuals(0.01, 1e-4), ("a warning",), refinement="images",
                             motion_diagnostics=motion,
                             plausibility=(PlausibilityItem("intrinsics", "a doubt", "cam1"),),
                             uncertainty={SETUP_KEYS[setup][0]: unc})


@pytest.mark.parametrize("setup", sorted(SETUP_KEYS))
def test_outputs_doc_names_every_calibration_json_key(setup):
    data = calibration_to_dict(_record(setup))
    keys = set(data) | set(data["residuals"])
    for cam in data["cameras"].values():
        keys |= set(cam) | set(cam["residuals"]) | set(cam["rejected"][0])
        keys |= set(cam["intrinsics"]) | set(cam["intrinsics"]["projection_std_px"])
        keys |= set(cam["intrinsics"]["lens_curve"])
        keys |= set(cam["uncertainty"]) | set(cam["uncertainty"]["T_ref_cam"])
    keys |= set(data["uncertainty"])
    for numbers in data["motion_diagnostics"].values():
        keys |= set(numbers)
    keys |= set(data["plausibility"][0])
    section = _sections("outputs.md")[2]
    assert sorted(k for k in keys if not _named(section, k)) == []


def test_outputs_doc_names_every_details_json_key():
    intr = Intrinsics(K=np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]), dist=np.zeros(4),
                      width=640, height=480)
    n = 3
    cam = CameraDetails("cam0", np.eye(4), intr, 0, ("a.png", "b.png", "c.png"),
                        np.arange(n, dtype=float), np.zeros(n), np.zeros(n), np.zeros(n),
                        np.tile(np.eye(4), (n, 1, 1)), {})
    traj = TrajectoryDetails("T_world_marker", np.arange(4.0), np.zeros((4, 3)), 4)
    data = run_details_to_dict(RunDetails("eye-to-base", "cam0", (cam,), (traj,)))
    entry = data["cameras"]["cam0"]
    keys = (set(data) | set(data["trajectories"][0]) | set(entry) | set(entry["intrinsics"])
            | set(entry["measurements"]) | set(data.get("timings_s", {})))
    keys |= {"timings_s", "reading", "detection", "pairing", "closed_form", "refinement",
             "outputs", "total"}
    section = _sections("outputs.md")[3]
    assert sorted(k for k in keys if not _named(section, k)) == []


def test_outputs_doc_names_the_other_files():
    s = _sections("outputs.md")
    for fmt, name in FORMATS.items():
        row = next(line for line in s[6].splitlines() if line.startswith(f"| `{fmt}` |"))
        assert f"`export/{name}`" in row
    for name in FIGURES:
        assert _named(s[5], f"figures/{name}")
    for name in ("calibration.json", "details.json", "camchain.yaml", "report.html"):
        assert _named(s[1], f"OUT/{name}")
