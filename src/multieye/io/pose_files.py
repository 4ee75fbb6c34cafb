"""One pose file beside each image: ``pos3.bmp`` + ``pos3.txt``, ``12.jpg`` + ``12.json``.

Robot toolkits store the pose of each image in a file of the same stem. ``rig.yaml``'s
``mocap.file`` names them with ``{stem}`` (``"{stem}.json"`` beside each image, or
``"poses/{stem}.yaml"`` in a folder of the dataset, as ROS-industrial stores them);
docs/rig-yaml.md, section 4, describes the keys this module reads:

- ``key`` (JSON and YAML files): the key that holds the pose (a dotted path such as ``pose.matrix``
  goes into nested objects);
- ``rotation``: ``quaternion-xyzw`` (default), ``quaternion-wxyz``, ``matrix``, ``rotvec``,
  ``euler-<axes>-deg`` or ``euler-<axes>-rad`` (axes as scipy's ``Rotation.from_euler``
  reads them: ``xyz`` extrinsic, ``XYZ`` intrinsic);
- ``values``: the order of plain numbers (default ``x y z`` then the rotation's numbers:
  ``qx qy qz qw``, ``qw qx qy qz``, ``rx ry rz`` for a rotation vector, ``a1 a2 a3`` for Euler
  angles in the order of the axes; ``rx ry rz`` for Euler angles name the angle about each
  axis when the axes are x, y and z once each);
- ``unit``: ``m`` (default), ``cm`` or ``mm`` for the translation.

A pose stored as 16 numbers (or 12, the top three rows), or as a JSON 4x4 (or 3x4) array,
is ``rotation: matrix`` (row-major, translation in the last column). A JSON or YAML mapping
of numbers (``{"x": 0.5, ..., "qx": 0.1, ...}``) gives the values by name, its rotation by
the names (unless ``rotation`` or ``values`` say otherwise): ``qx qy qz qw`` a quaternion,
``rx ry rz`` a rotation vector; a ROS ``geometry_msgs/Pose`` mapping (``position: {x, y,
z}``, ``orientation: {x, y, z, w}``) a quaternion.  Both quaternion and rotation-vector
names, or a key that is none of these, is refused naming the key. Every problem is a
:class:`DatasetError` naming the pose file and what was expected.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from multieye.core import geometry
from multieye.core.errors import DatasetError
from multieye.core.limits import MAX_POSITION_M, MAX_TABLE_BYTES, MAX_YAML_BYTES
from multieye.core.regular_files import read_bounded
from multieye.io.textfile import length_scale
from multieye.io.yamlfile import load_yaml

__all__ = ["STEM", "ROTATION_NAMES", "PoseFormat", "check_rotation", "default_values",
           "read_pose_file", "pose_file_pattern", "poses_by_name", "read_pose_table", "NonFinitePose",
           "poses_by_table", "read_order_table", "poses_by_order"]

#: The placeholder of ``mocap.file`` for the image's stem.
STEM = "{stem}"
#: The rotation conventions (``euler-<axes>-deg|rad`` stands for every axes sequence).
ROTATION_NAMES = ("quaternion-xyzw", "quaternion-wxyz", "matrix", "rotvec",
                  "euler-<axes>-deg", "euler-<axes>-rad")
_EULER = re.compile(r"^euler-([xyz]{3}|[XYZ]{3})-(deg|rad)$")
#: Largest ``|R^T R - I|`` entry and ``|det R - 1|`` of a rotation matrix read from a file
#: (robot controllers print 6 decimals or fewer).
MATRIX_TOLERANCE = 1e-3
#: Largest accepted ``| ||q|| - 1 |``.
QUATERNION_TOLERANCE = 1e-3


def check_rotation(name: object) -> str:
    """``name`` if it is a rotation convention; ValueError saying what was expected."""
    if isinstance(name, str) and (name in ROTATION_NAMES[:4] or _EULER.match(name)):
        if _EULER.match(name):
            axes = _EULER.match(name).group(1)
            if any(axes[i] == axes[i + 1] for i in range(2)):
                raise ValueError(f"Euler axes must not repeat an axis twice in a row, got "
                                 f"{axes!r}")
        return name
    raise ValueError(f"expected one of quaternion-xyzw, quaternion-wxyz, matrix, rotvec, "
                     f"euler-<axes>-deg, euler-<axes>-rad (axes such as xyz, ZYX), got {name!r}")


def default_values(rotation: str) -> tuple[str, ...]:
    """The order of plain numbers when ``values`` is not given."""
    rot = {"quaternion-xyzw": ("qx", "qy", "qz", "qw"),
           "quaternion-wxyz": ("qw", "qx", "qy", "qz"),
           "rotvec": ("rx", "ry", "rz")}.get(rotation, ("a1", "a2", "a3"))
    return ("x", "y", "z") + rot


def _rotation_names(rotation: str) -> tuple[set[str], ...]:
    """The sets of names ``values`` may use for the rotation's numbers."""
    if rotation.startswith("quaternion"):
        return ({"qx", "qy", "qz", "qw"},)
    if rotation == "rotvec":
        return ({"rx", "ry", "rz"},)
    axes = _EULER.match(rotation).group(1).lower()
    names = [{"a1", "a2", "a3"}]
    if sorted(axes) == ["x", "y", "z"]:
        names.append({"rx", "ry", "rz"})
    return tuple(names)


def check_values(values: object, rotation: str, *, stamped: bool = False) -> tuple[str, ...]:
    """``values`` as a tuple of names if they fit ``rotation`` (``stamped``: with ``t``, the
    time stamp); ValueError otherwise."""
    if rotation == "matrix":
        raise ValueError("a matrix is read as 16 (or 12) numbers, row-major; leave out "
                         "'values'")
    if not isinstance(values, (list, tuple)) or not all(isinstance(v, str) for v in values):
        raise ValueError(f"expected a list of names, got {values!r}")
    got = set(values)
    base = {"x", "y", "z"} | ({"t"} if stamped else set())
    for rot in _rotation_names(rotation):
        if len(values) == len(base) + len(rot) and got == base | rot:
            return tuple(values)
    first = "t, x, y, z, " if stamped else "x, y, z, "
    options = " or ".join(first + ", ".join(sorted(r)) for r in _rotation_names(rotation))
    raise ValueError(f"expected each of {options} once (for {rotation}), got "
                     f"{', '.join(map(str, values))}")


@dataclass(frozen=True)
class PoseFormat:
    """How to read one pose file (docs/rig-yaml.md, section 4)."""

    rotation: str = "quaternion-xyzw"
    values: tuple[str, ...] | None = None
    key: str | None = None
    unit: str = "m"

    @property
    def order(self) -> tuple[str, ...]:
        return self.values if self.values is not None else default_values(self.rotation)


def pose_file_pattern(pattern: str, image: Path) -> Path:
    """The pose file of an image: ``pattern`` with ``{stem}`` replaced, beside the image (or,
    for an absolute ``pattern``, in its folder)."""
    folder, name = _pattern_place(pattern, image.parent)
    return folder / name.replace(STEM, image.stem)


def _pattern_place(pattern: str, image_folder: Path) -> tuple[Path, str]:
    """The folder a ``{stem}`` pattern's files are in and their name pattern."""
    p = Path(pattern)
    return (p.parent, p.name) if p.is_absolute() else (image_folder, pattern)


def _numbers_from_text(path: Path) -> list[float]:
    text = read_bounded(path, what="pose file", max_bytes=MAX_YAML_BYTES).decode(
        "utf-8-sig", errors="replace")
    cells = [c for line in text.splitlines() for c in re.split(r"[\s,;]+", line.split("#")[0])
             if c]
    out = []
    for c in cells:
        try:
            out.append(float(c))
        except ValueError:
            raise DatasetError(f"expected numbers only, got {c!r}", path=path) from None
    return out


def _from_document(path: Path, fmt: PoseFormat):
    """The value of a JSON or YAML pose file that holds the pose (under ``fmt.key``)."""
    if path.suffix.lower() in (".yaml", ".yml"):
        data = load_yaml(path, what="pose file").data
    else:
        try:
            data = json.loads(read_bounded(path, what="pose file", max_bytes=MAX_YAML_BYTES
                                           ).decode("utf-8-sig"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise DatasetError(f"not a JSON file: {exc}", path=path) from None
        except RecursionError:
            raise DatasetError("not a JSON file: nested too deeply", path=path) from None
    if fmt.key is not None:
        for part in fmt.key.split("."):
            if not isinstance(data, Mapping) or part not in data:
                have = (f"; its keys: {', '.join(map(str, data))}" if isinstance(data, Mapping)
                        else "")
                raise DatasetError(f"no key {fmt.key!r} (mocap.key){have}", path=path)
            data = data[part]
    elif (isinstance(data, Mapping) and not _ros_pose(data)
          and not any(isinstance(k, str) and k in _NAMED for k in data)):
        raise DatasetError(f"a mapping without named numbers (x y z ...): give mocap.key, the "
                           f"key that holds the pose (keys: {', '.join(map(str, data))})",
                           path=path)
    return data


#: The names a mapping of named numbers may use.
_NAMED = ("x", "y", "z", "qx", "qy", "qz", "qw", "rx", "ry", "rz", "a1", "a2", "a3")


def _ros_pose(data: Mapping) -> bool:
    """A ROS ``geometry_msgs/Pose``: ``position: {x, y, z}``, ``orientation: {x, y, z, w}``."""
    return (set(data) == {"position", "orientation"}
            and all(isinstance(data[k], Mapping) for k in data))


def _mapping_pose(data: Mapping, fmt: PoseFormat, scale: float, path: Path) -> np.ndarray:
    """The pose of a mapping of named numbers (module docstring), its form checked."""
    if _ros_pose(data):
        pos, ori = data["position"], data["orientation"]
        for key, part, names in (("position", pos, "xyz"), ("orientation", ori, "xyzw")):
            if set(part) != set(names):
                raise DatasetError(f"key {key!r}: expected the numbers {', '.join(names)}, got "
                                   f"{', '.join(map(str, part))}", path=path)
        values = {"x": pos["x"], "y": pos["y"], "z": pos["z"], "qx": ori["x"], "qy": ori["y"],
                  "qz": ori["z"], "qw": ori["w"]}
        return _named(values, PoseFormat("quaternion-xyzw", None, None, fmt.unit), scale, path)
    if fmt.values is None and fmt.rotation == "quaternion-xyzw":
        quat = [k for k in ("qx", "qy", "qz", "qw") if k in data]
        rvec = [k for k in ("rx", "ry", "rz") if k in data]
        if quat and rvec:
            raise DatasetError(f"keys {', '.join(quat + rvec)}: both a quaternion and a rotation "
                               "vector; keep one (or give mocap.rotation)", path=path)
        fmt = replace(fmt, rotation="rotvec" if rvec else "quaternion-xyzw")
    elif fmt.values is None and fmt.rotation.startswith("euler-"):
        # the angles named as the mapping names them: a1 a2 a3, or rx ry rz about each axis
        named = [s for s in _rotation_names(fmt.rotation) if s <= set(data)]
        if named:
            fmt = replace(fmt, values=("x", "y", "z", *sorted(named[-1])))
    for key, value in data.items():
        if key not in fmt.order:
            raise DatasetError(f"key {key!r}: not one of the pose's numbers "
                               f"{' '.join(fmt.order)} (rotation {fmt.rotation}); give "
                               "mocap.key for a pose under a key", path=path)
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise DatasetError(f"key {key!r}: expected a number, got {str(value)[:40]!r}",
                               path=path)
    return _named(data, fmt, scale, path)


def _numeric_mapping(data: Mapping) -> bool:
    return bool(data) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                              for v in data.values())


def _flat_numbers(data, path: Path) -> tuple[list[float], bool]:
    """Numbers of a JSON value and whether it was an array of rows (a matrix)."""
    rows = isinstance(data, list) and bool(data) and all(isinstance(r, list) for r in data)
    flat = [x for r in data for x in r] if rows else data
    if not isinstance(flat, list) or not all(isinstance(x, (int, float))
                                             and not isinstance(x, bool) for x in flat):
        raise DatasetError(f"expected the pose as numbers (a list, a 4x4 array or an object of "
                           f"named numbers), got {json.dumps(data)[:80]}", path=path)
    if rows and {len(r) for r in data} != {4}:
        raise DatasetError(f"expected a 4x4 (or 3x4) array, got rows of "
                           f"{sorted({len(r) for r in data})} numbers", path=path)
    return [float(x) for x in flat], rows


def _matrix(numbers: Sequence[float], scale: float, path: Path) -> np.ndarray:
    T = np.eye(4)
    T[:len(numbers) // 4] = np.reshape(numbers, (-1, 4))
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-9):
        raise DatasetError(f"expected a 4x4 pose whose last row is 0 0 0 1, got "
                           f"{' '.join(f'{v:g}' for v in T[3])}", path=path)
    R = T[:3, :3]
    ortho = float(np.abs(R.T @ R - np.eye(3)).max())
    det = float(np.linalg.det(R))
    if not (ortho <= MATRIX_TOLERANCE and abs(det - 1) <= MATRIX_TOLERANCE):
        raise DatasetError(f"expected a rotation matrix (orthonormal, det 1) in the pose's "
                           f"upper-left 3x3, got |R^T R - I| = {ortho:.2g}, det R = {det:.6g}",
                           path=path)
    u, _, vt = np.linalg.svd(R)
    return geometry.make_transform(u @ vt, T[:3, 3] * scale)


def _rotation(rotation: str, v: Mapping[str, float], path: Path, order=()) -> np.ndarray:
    from scipy.spatial.transform import Rotation  # noqa: PLC0415 (heavy: scipy.spatial, 0.2-0.3 CPU-s for every process that imports multieye.io, the report's figure worker included)

    if rotation.startswith("quaternion"):
        q = np.array([v["qx"], v["qy"], v["qz"], v["qw"]])
        norm = float(np.linalg.norm(q))
        if not abs(norm - 1) <= QUATERNION_TOLERANCE:
            raise DatasetError(f"quaternion (qx qy qz qw) must have unit norm, got norm {norm:.6g} "
                               f"(tolerance {QUATERNION_TOLERANCE:g}) with the numbers read as "
                               f"{' '.join(order)} (values: in rig.yaml orders them)", path=path)
        return Rotation.from_quat(q / norm).as_matrix()
    if rotation == "rotvec":
        return Rotation.from_rotvec([v["rx"], v["ry"], v["rz"]]).as_matrix()
    axes, unit = _EULER.match(rotation).groups()
    if "a1" in v:
        angles = [v["a1"], v["a2"], v["a3"]]
    else:
        angles = [v["r" + a] for a in axes.lower()]
    return Rotation.from_euler(axes, angles, degrees=unit == "deg").as_matrix()


class NonFinitePose(DatasetError):
    """A pose file holding ``nan`` or ``inf`` (a tracking dropout): its image is left out
    (:func:`poses_by_name`), as a pose table's row of such values is."""


def read_pose_file(path: str | os.PathLike, fmt: PoseFormat) -> np.ndarray:
    """The 4x4 pose (metres) one file holds.

    Raises
    ------
    DatasetError
        Unreadable file, a missing key, the wrong count of numbers, a non-rotation matrix, a
        non-unit quaternion or a non-finite or absurd value; the message names the file and
        what was expected.
    """
    path = Path(path)
    scale = length_scale(fmt.unit)
    try:
        if path.suffix.lower() in (".json", ".yaml", ".yml"):
            data = _from_document(path, fmt)
            if isinstance(data, Mapping):
                if fmt.rotation == "matrix":
                    raise DatasetError("expected a 4x4 array or 16 numbers for rotation: "
                                       "matrix, got a mapping of named numbers", path=path)
                return _mapping_pose(data, fmt, scale, path)
            numbers, rows = _flat_numbers(data, path)
        else:
            numbers, rows = _numbers_from_text(path), False
    except OSError as exc:
        raise DatasetError(f"cannot read the pose file: {exc.strerror or exc}",
                           path=path) from None
    if not all(np.isfinite(numbers)):
        raise NonFinitePose("expected finite numbers, got nan or inf", path=path)
    if rows or fmt.rotation == "matrix" or (len(numbers) == 16 and fmt.values is None):
        if len(numbers) not in (12, 16):
            raise DatasetError(f"expected 16 numbers (a 4x4 pose, row-major) or 12 (its top "
                               f"three rows), got {len(numbers)}", path=path)
        return _checked(_matrix(numbers, scale, path), path)
    order = fmt.order
    if len(numbers) != len(order):
        raise DatasetError(f"expected {len(order)} numbers ({' '.join(order)}; rotation "
                           f"{fmt.rotation}), got {len(numbers)}", path=path)
    return _named(dict(zip(order, numbers)), fmt, scale, path)


def _named(values: Mapping, fmt: PoseFormat, scale: float, path: Path) -> np.ndarray:
    if fmt.rotation == "matrix":
        raise DatasetError("expected a 4x4 array or 16 numbers for rotation: matrix, got an "
                           "object of named numbers", path=path)
    if not _numeric_mapping(values):
        raise DatasetError("expected an object of named numbers", path=path)
    need = fmt.order
    missing = [n for n in need if n not in values]
    if missing:
        raise DatasetError(f"expected the numbers {', '.join(need)} (rotation {fmt.rotation}), "
                           f"missing {', '.join(missing)}", path=path)
    v = {n: float(values[n]) for n in need}
    if not all(np.isfinite(list(v.values()))):
        raise NonFinitePose("expected finite numbers, got nan or inf", path=path)
    T = geometry.make_transform(_rotation(fmt.rotation, v, path, fmt.order),
                                np.array([v["x"], v["y"], v["z"]]) * scale)
    return _checked(T, path)


def _checked(T: np.ndarray, path: Path) -> np.ndarray:
    if not np.all(np.abs(T[:3, 3]) <= MAX_POSITION_M):
        raise DatasetError(f"absurd position: {np.abs(T[:3, 3]).max():g} m, beyond "
                           f"{MAX_POSITION_M:g} m (mocap.unit?)", path=path)
    return T


def _natural(path: Path) -> tuple:
    """Sort key: ``pos2`` before ``pos10``."""
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t)
                 for t in re.split(r"(\d+)", path.name) if t)


def poses_by_name(images: Sequence[Path], pattern: str, fmt: PoseFormat
                  ) -> tuple[list[tuple[Path, np.ndarray]], list[tuple[str, str]]]:
    """Each image with the pose of its file (``pattern`` with ``{stem}``, beside the image).

    Returns
    -------
    matched : list of (image, 4x4 pose)
        In natural name order (``pos2`` before ``pos10``).
    unmatched : list of (name, reason)
        Images without a pose file or whose pose file holds ``nan`` or ``inf`` (a dropout:
        the image is left out, as a pose table's row of such values leaves its image out),
        and pose files (names that fit ``pattern``) without an image.

    Raises
    ------
    DatasetError
        Any other pose file that cannot be read (:func:`read_pose_file`).
    """
    matched, unmatched, stems = [], [], set()
    for image in sorted(images, key=_natural):
        stems.add(image.stem)
        pose = pose_file_pattern(pattern, image)
        if pose.is_file():
            try:
                matched.append((image, read_pose_file(pose, fmt)))
            except NonFinitePose:
                unmatched.append((image.name, f"pose file {pose.name} holds nan or inf"))
        else:
            unmatched.append((image.name, f"no pose file {pose.name}"))
    for folder in sorted({image.parent for image in images}):
        folder, name = _pattern_place(pattern, folder)
        head, _, tail = name.partition(STEM)
        fits = re.compile(re.escape(head) + "(.+)" + re.escape(tail.replace(STEM, "*")) + "$")
        for p in sorted(folder.glob(name.replace(STEM, "*")), key=_natural):
            rel = p.relative_to(folder).as_posix()
            m = fits.match(rel)
            if p.is_file() and m and m.group(1) not in stems:
                unmatched.append((rel, f"pose file without an image {m.group(1)}.*"))
    return matched, unmatched


def read_pose_table(path: str | os.PathLike, fmt: PoseFormat
                    ) -> dict[str, tuple[np.ndarray | None, int]]:
    """A table of poses with an ``image`` column (``match: image``): image name -> (pose, line);
    the pose is None for a row holding a value that is not a finite number (left out).

    The first line that is not a comment (``#``) is the header; cells are separated by
    commas, else semicolons, else white space. Besides ``image`` (any case), the columns are
    the names of ``values`` (any order, any case), else 16 (or 12) numbers of a matrix, else
    the numbers in the order of ``values``.

    Raises
    ------
    DatasetError
        No ``image`` column, the wrong count of cells, a bad pose or an image named twice;
        the message names the file and the line.
    """
    out: dict[str, tuple[np.ndarray, int]] = {}
    for image, T, n in _table_rows(Path(path), fmt, image_column=True):
        if image in out:
            raise DatasetError(f"image {image} has a pose on line {out[image][1]} already",
                               path=path, line=n)
        out[image] = (T, n)
    return out


def read_order_table(path: str | os.PathLike, fmt: PoseFormat
                     ) -> list[tuple[np.ndarray | None, int]]:
    """A table of poses whose rows follow the images sorted by name (``match: order``, as
    KUKA's ``RobotPosesVec.txt``): ``(pose, line)`` per row, in file order; the pose is None
    for a row holding a value that is not a finite number (left out, keeping its place).

    A header is optional: a first line (not a ``#`` comment) with a cell that is not a
    number is the header, and its cells name the columns as in :func:`read_pose_table`
    (without ``image``); without one, each row holds 16 (or 12) numbers of a matrix
    (row-major) when ``values`` is not given, else the numbers in the order of ``values``.

    Raises
    ------
    DatasetError
        The wrong count of cells or a bad pose, naming the file and the line.
    """
    return [(T, n) for _, T, n in _table_rows(Path(path), fmt, image_column=False)]


def _table_rows(path: Path, fmt: PoseFormat, *, image_column: bool):
    """``(image or None, pose, line)`` for each row of a pose table (docs/rig-yaml.md,
    section 4, "Pose tables"); the pose is None for a row holding ``nan`` or ``inf``."""
    what = "the pose table" + (" (match: image)" if image_column else " (match: order)")
    try:
        text = read_bounded(path, what="pose table", max_bytes=MAX_TABLE_BYTES).decode(
            "utf-8-sig", errors="replace")
    except OSError as exc:
        raise DatasetError(f"cannot read {what}: {exc.strerror or exc}", path=path) from None
    rows = [(n, line) for n, line in enumerate(text.splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        expected = ("a header with an 'image' column" if image_column
                    else "one row of numbers per image")
        raise DatasetError(f"empty pose table: expected {expected}", path=path)
    head_line, head = rows[0]
    sep = "," if "," in head else ";" if ";" in head else None
    names = [c.strip().lower() for c in (head.split(sep) if sep else head.split())]
    col = None
    if image_column:
        if "image" not in names:
            raise DatasetError(f"expected a header with a column 'image' (match: image), got "
                               f"{', '.join(names)}", path=path, line=head_line)
        col = names.index("image")
        body = rows[1:]
    elif all(_is_number(c) for c in names):
        names, body = None, rows                    # no header: numbers from the first line
    else:
        body = rows[1:]
    others = None if names is None else [n for i, n in enumerate(names) if i != col]
    by_name = (others is not None and set(fmt.order) <= set(others)
               and fmt.rotation != "matrix")
    scale = length_scale(fmt.unit)
    for n, line in body:
        cells = [c.strip() for c in (line.split(sep) if sep else line.split())]
        if names is not None and len(cells) != len(names):
            raise DatasetError(f"expected {len(names)} cells ({', '.join(names)}), got "
                               f"{len(cells)}", path=path, line=n)
        image = cells.pop(col) if col is not None else None
        try:
            numbers = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_number(c))
            besides = " besides the image name" if col is not None else ""
            comma = ("; a decimal comma: write numbers with a decimal point (0.5, not 0,5)"
                     if re.fullmatch(r"[-+]?\d*,\d+", bad) else "")
            raise DatasetError(f"expected numbers{besides}, got {bad!r}{comma}", path=path,
                               line=n) from None
        if not all(np.isfinite(numbers)):      # left out, its image listed (as TUM rows)
            yield image, None, n
            continue
        try:
            if by_name:
                T = _named(dict(zip(others, numbers)), fmt, scale, path)
            elif fmt.rotation == "matrix" or (len(numbers) in (12, 16) and fmt.values is None):
                if len(numbers) not in (12, 16):
                    raise DatasetError(f"expected 16 numbers (a 4x4 pose, row-major) or 12, got "
                                       f"{len(numbers)}", path=path)
                T = _checked(_matrix(numbers, scale, path), path)
            elif len(numbers) != len(fmt.order):
                kind, got = (("columns", ", ".join(others)) if others is not None
                             else ("numbers", f"{len(numbers)} numbers"))
                besides = " besides image" if col is not None else ""
                raise DatasetError(f"expected the {kind} {', '.join(fmt.order)}{besides} "
                                   f"(rotation {fmt.rotation}), or 16 (or 12) numbers of a "
                                   f"4x4 matrix, got {got}", path=path)
            else:
                T = _named(dict(zip(fmt.order, numbers)), fmt, scale, path)
        except DatasetError as exc:
            raise DatasetError(exc.reason, path=path, line=n) from None
        yield image, T, n


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def poses_by_table(images: Sequence[Path], table: str | os.PathLike, fmt: PoseFormat
                   ) -> tuple[list[tuple[Path, np.ndarray]], list[tuple[str, str]]]:
    """Each image with the row of ``table`` whose ``image`` cell is its name or its stem;
    returns what :func:`poses_by_name` returns (rows without an image are listed as
    ``<table> line <n>``)."""
    rows = read_pose_table(table, fmt)
    matched, unmatched, used = [], [], set()
    for image in sorted(images, key=_natural):
        cell = image.name if image.name in rows else image.stem if image.stem in rows else None
        if cell is None:
            unmatched.append((image.name, f"no row for it in {Path(table).name}"))
        elif rows[cell][0] is None:
            used.add(cell)
            unmatched.append((image.name, _not_finite(table, rows[cell][1])))
        else:
            used.add(cell)
            matched.append((image, rows[cell][0]))
    for cell, (_, line) in rows.items():
        if cell not in used:
            unmatched.append((f"{Path(table).name} line {line}",
                              f"pose row without an image: {cell}"))
    return matched, unmatched


def poses_by_order(images: Sequence[Path], table: str | os.PathLike, fmt: PoseFormat
                   ) -> tuple[list[tuple[Path, np.ndarray]], list[tuple[str, str]]]:
    """Each image, in natural name order (``pos2`` before ``pos10``), with the row of
    ``table`` at its place (``match: order``); returns what :func:`poses_by_name` returns
    (unmatched: the images whose row holds ``nan`` or ``inf``).

    Raises
    ------
    DatasetError
        A bad row (:func:`read_order_table`), or as many rows as images not: one line naming
        both counts.
    """
    rows = read_order_table(table, fmt)
    ordered = sorted(images, key=_natural)
    if len(rows) != len(ordered):
        folder = ordered[0].parent.name + "/" if ordered else "the camera's folder"
        raise DatasetError(f"match: order pairs row k with image k, but the table has "
                           f"{len(rows)} pose rows and {folder} {len(ordered)} images; give "
                           f"one row per image, in the images' name order", path=table)
    return ([(image, T) for image, (T, _) in zip(ordered, rows) if T is not None],
            [(image.name, _not_finite(table, n)) for image, (T, n) in zip(ordered, rows)
             if T is None])


def _not_finite(table: str | os.PathLike, line: int) -> str:
    return f"pose row left out: {Path(table).name} line {line} holds nan or inf"
