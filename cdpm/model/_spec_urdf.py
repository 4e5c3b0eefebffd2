"""The URDF a spec names: found (beside the spec or in an installed data
package), read safely (:mod:`cdpm.model.urdf_check`) and built into a Pinocchio
model, with the URDF parser's own messages turned into spec problems."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from cdpm.errors import SpecError, short_repr
from cdpm.model._spec_parts import WORLD_FRAME_NAMES, Problems, unknown_keys, unprintable_name
from cdpm.model.urdf_check import read_urdf

#: pip distribution that installs a ROS-style package's files, where the
#: names differ (used in the install hint when a package is missing).
_PACKAGE_PIP_NAMES = {"example-robot-data": "example-robot-data (or: pip install 'cdpm[robots]')"}


def usable_path(path: str | os.PathLike) -> Path:
    """``path`` expanded and resolved, checked to be one the system can
    look up (no NUL character, not too long).

    Raises:
        SpecError: the path cannot name a file, with the reason.
    """
    text = os.fspath(path)
    if "\0" in str(text):
        raise SpecError(f"the path {short_repr(text)} contains a NUL character; no file has it")
    try:
        resolved = Path(text).expanduser().resolve()
        resolved.is_dir()  # a name too long for the system fails here
    except (OSError, ValueError, RuntimeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc)
        raise SpecError(f"cannot use the path {short_repr(text)}: {reason}") from None
    return resolved


def package_share_directory(package: str) -> Path | None:
    """Directory of an installed ROS-style data package, or None.

    Looks in the Python distribution of that name (cmeel layout, e.g.
    ``example-robot-data`` installs ``<site-packages>/cmeel.prefix/share/
    example-robot-data``), then in ``$ROS_PACKAGE_PATH`` and
    ``$AMENT_PREFIX_PATH``.
    """
    # importlib.metadata (43 modules): only package:// URIs need it
    from importlib import metadata

    try:
        dist = metadata.distribution(package)
    except metadata.PackageNotFoundError:
        dist = None
    if dist is not None:
        candidate = Path(str(dist.locate_file(f"cmeel.prefix/share/{package}")))
        if candidate.is_dir():
            return candidate
    for var in ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH"):
        for root in filter(None, os.environ.get(var, "").split(os.pathsep)):
            for candidate in (Path(root) / package, Path(root) / "share" / package):
                if candidate.is_dir():
                    return candidate
    return None


def _package_urdf(problems: Problems, urdf: Any) -> Path | None:
    """Resolve ``{package: NAME, path: REL}`` or ``package://NAME/REL``."""
    if isinstance(urdf, str):
        package, _, rel = urdf[len("package://") :].partition("/")
    else:
        unknown_keys(problems, "urdf", urdf, ("package", "path"))
        package, rel = urdf.get("package"), urdf.get("path")
        if not isinstance(package, str) or not isinstance(rel, str):
            problems.add(
                "urdf",
                "a packaged URDF needs {package: NAME, path: PATH/IN/PACKAGE.urdf}, got "
                f"{urdf!r}",
            )
            return None
    if not package or not rel:
        problems.add("urdf", f"{urdf!r}: expected package://PACKAGE/PATH/TO/FILE.urdf")
        return None
    root = package_share_directory(package)
    if root is None:
        pip_name = _PACKAGE_PIP_NAMES.get(package, package)
        problems.add(
            "urdf",
            f"package {package!r} is not installed (it provides the URDF {rel!r}); "
            f"install it with: pip install {pip_name}",
        )
        return None
    try:
        urdf_path = usable_path(root / rel)
    except SpecError as exc:
        problems.add("urdf", str(exc))
        return None
    if not urdf_path.is_file():
        problems.add("urdf", f"{rel!r} not found in package {package!r} (looked for {urdf_path})")
        return None
    return urdf_path


def load_urdf(problems: Problems, spec_path: Path, urdf: Any):
    if urdf is None:
        problems.add("urdf", "missing; give the URDF file's path relative to the spec")
        return None, None
    if isinstance(urdf, dict) or (isinstance(urdf, str) and urdf.startswith("package://")):
        urdf_path = _package_urdf(problems, urdf)
        if urdf_path is None:
            return None, None
        return build_model(problems, urdf_path), urdf_path
    if not isinstance(urdf, str):
        problems.add("urdf", f"expected a file path or {{package, path}}, got {urdf!r}")
        return None, None
    try:
        urdf_path = usable_path(spec_path.parent / urdf)
    except SpecError as exc:
        problems.add("urdf", str(exc))
        return None, None
    if not urdf_path.is_file():
        nearby = sorted(p.name for p in spec_path.parent.glob("*.urdf"))
        hint = f"; URDF files beside the spec: {', '.join(nearby)}" if nearby else ""
        problems.add("urdf", f"file {urdf!r} not found (looked for {urdf_path}){hint}")
        return None, None
    return build_model(problems, urdf_path), urdf_path


def build_model(problems: Problems, urdf_path: Path):
    """Build a Pinocchio model from a URDF, recording a problem on failure
    (the file is checked by :func:`cdpm.model.urdf_check.read_urdf` first)."""
    # pinocchio: loaded on first use
    import pinocchio as pin

    _, urdf_problems = read_urdf(urdf_path)
    if urdf_problems:
        for problem in urdf_problems:
            problems.add("urdf", problem)
        return None
    with _captured_stderr() as said:
        try:
            model = pin.buildModelFromUrdf(str(urdf_path))
        except (ValueError, RuntimeError) as exc:
            model, error = None, exc
    # the URDF parser's own lines (printed to the process's stderr) say
    # what is wrong; keep the first and drop the source locations
    lines = [ln.strip().removeprefix("Error:").strip() for ln in said.text.splitlines()]
    detail = next((ln for ln in lines if ln and not ln.startswith("at line")), "")
    if model is None:
        problems.add(
            "urdf", f"Pinocchio could not read {urdf_path.name}: {detail or error}".rstrip()
        )
        return None
    if detail:  # e.g. a visual element it skipped: the dynamics are read
        warnings.warn(f"{urdf_path.name}: the URDF parser reported: {detail}", stacklevel=3)
    unprintable = _unprintable_names(model)
    if unprintable:
        for kind, problem in unprintable:
            problems.add("urdf", f"{urdf_path.name}: the {kind} name {problem}: rename the {kind}")
        return None  # its names would be printed in later messages and reports
    return model


def _unprintable_names(model) -> list[tuple[str, str]]:
    """(kind, problem) of each link, joint or frame of the model whose name
    cannot be printed (:func:`~cdpm.model._spec_parts.unprintable_name`)."""
    # pinocchio: loaded on first use
    import pinocchio as pin

    kinds = {
        pin.FrameType.BODY: "link",
        pin.FrameType.JOINT: "joint",
        pin.FrameType.FIXED_JOINT: "joint",
    }
    found: list[tuple[str, str]] = []
    seen: set[str] = set()
    for frame in model.frames:
        if frame.name in seen:  # a link and its joint may share a name
            continue
        seen.add(frame.name)
        problem = unprintable_name(frame.name)
        if problem is not None:
            found.append((kinds.get(frame.type, "frame"), problem))
    return found


class _Captured:
    text = ""


@contextlib.contextmanager
def _captured_stderr():
    """Collect what C++ code writes to file descriptor 2 (the URDF parser
    prints its errors there) instead of letting it reach the terminal."""
    captured = _Captured()
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable descriptor 2: nothing to capture
        yield captured
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield captured
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            captured.text = sink.read(20_000).decode("utf-8", "replace")


class FrameTable:
    """Names a route may use, and each link's centre of mass."""

    def __init__(self, model, link_coms: dict[str, np.ndarray]) -> None:
        self.model = model
        self.names: dict[str, int] = {}
        for fid, frame in enumerate(model.frames):
            if frame.name == "universe":
                continue
            self.names.setdefault(frame.name, fid)
        self.link_coms = link_coms

    def listing(self) -> str:
        names = ["world", *sorted(self.names)]
        more = f", ... ({len(names) - 30} more)" if len(names) > 30 else ""
        return ", ".join(names[:30]) + more

    def exists(self, name: str) -> bool:
        return name in WORLD_FRAME_NAMES or name in self.names

    def com_in_frame(self, name: str) -> np.ndarray | None:
        """Centre of mass of the link ``name`` in that link's frame [m], or
        None when ``name`` is not a link with a positive mass."""
        return self.link_coms.get(name)


def link_coms(urdf_path: Path) -> dict[str, np.ndarray]:
    """Centre of mass of every URDF link with a positive mass, in its frame.

    Pinocchio merges link inertias into their joint's and keeps no per-link
    record, so the ``<inertial>`` origins are read from the URDF here.
    """

    coms: dict[str, np.ndarray] = {}
    root, _ = read_urdf(urdf_path)  # checked before the model was built
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass = inertial.find("mass")
        if mass is None or not float(mass.get("value", "0")) > 0:
            continue
        origin = inertial.find("origin")
        xyz = origin.get("xyz", "0 0 0") if origin is not None else "0 0 0"
        coms[link.get("name")] = np.array([float(x) for x in xyz.split()])
    return coms
