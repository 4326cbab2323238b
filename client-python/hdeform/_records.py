"""What the server answers, as frozen dataclasses (never raw protobuf): β, history steps,
timeline keys, timelines, named snapshots, rigs and upload repairs."""
import os
from dataclasses import dataclass, field
from typing import Any, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._proto import pb
from ._transforms import Transform

# StepKind, EASING_*: the proto enum's names without their prefix, lower case.
_STEP_KINDS = {
    pb.STEP_KIND_UNSPECIFIED: "unspecified", pb.STEP_KIND_CONSTRAINTS: "constraints",
    pb.STEP_KIND_BETA: "beta", pb.STEP_KIND_MOVE: "move", pb.STEP_KIND_UNDO: "undo",
    pb.STEP_KIND_REDO: "redo", pb.STEP_KIND_RESTORE: "restore",
    pb.STEP_KIND_TIMELINE: "timeline", pb.STEP_KIND_SNAPSHOT_SAVE: "snapshot_save",
    pb.STEP_KIND_SNAPSHOT_DELETE: "snapshot_delete"}
_EASING_NAMES = {pb.EASING_LINEAR: "linear", pb.EASING_SMOOTHSTEP: "smoothstep"}


def csv_text(lines: List[str], path: "Optional[Union[str, os.PathLike[str]]]") -> Optional[str]:
    """CSV lines as text, or written to `path` (then None): the CLI's line endings."""
    text = "\n".join(lines) + "\n"
    if path is None:
        return text
    with open(os.fspath(path), "w", newline="") as f:
        f.write(text)
    return None


@dataclass(frozen=True)
class Beta:
    """A β setting. value: the number (the pick when automatic); units: "area" or "raw";
    automatic: the server picks it; local_count: how many local entries (regions with their
    own β) it has."""
    value: float
    units: str = "area"
    automatic: bool = False
    local_count: int = 0

    @classmethod
    def from_proto(cls, b: Any) -> "Beta":
        return cls(value=float(b.value),
                   units="raw" if b.units == pb.BETA_UNITS_RAW else "area",
                   automatic=bool(b.automatic), local_count=len(b.local))


@dataclass(frozen=True)
class HistoryStep:
    """One step of a session's history (hdeform.v1.HistoryStep).

    id: 1, 2, … in the session's order; kind: "constraints", "beta", "move", "undo", "redo",
    "restore", "timeline", "snapshot_save" or "snapshot_delete"; client_id: its author's
    client id ("" anonymous); author: the display name at the time; time_unix_ms; version:
    the session version right after it; handles: the handles whose transforms it changed;
    beta_changed, timeline_changed; target: for undo / redo the step reverted / re-applied
    (else 0); snapshot: the snapshot's name for restore / snapshot_save / snapshot_delete
    (else ""); undone: reverted by a later undo and not redone; summary: for people, e.g.
    "moved handle 0"."""
    id: int
    kind: str
    client_id: str
    author: str
    time_unix_ms: int
    version: int
    handles: Tuple[int, ...]
    beta_changed: bool
    timeline_changed: bool
    target: int
    snapshot: str
    undone: bool
    summary: str

    @classmethod
    def from_proto(cls, s: Any) -> "HistoryStep":
        return cls(id=int(s.id), kind=_STEP_KINDS.get(s.kind, f"kind_{int(s.kind)}"),
                   client_id=str(s.client_id), author=str(s.author),
                   time_unix_ms=int(s.time_unix_ms), version=int(s.version),
                   handles=tuple(int(h) for h in s.handles),
                   beta_changed=bool(s.beta_changed), timeline_changed=bool(s.timeline_changed),
                   target=int(s.target), snapshot=str(s.snapshot), undone=bool(s.undone),
                   summary=str(s.summary))


@dataclass(frozen=True)
class Keyframe:
    """A timeline key, or the pose pose_at() interpolates. time_s: seconds; transforms: one
    hdeform.Transform per handle (update(transforms=list(k.transforms)) shows the pose);
    beta: the β from this key on, or None when the key sets none; easing: the key's own
    easing to the next key ("linear" | "smoothstep"), or None for the timeline's."""
    time_s: float
    transforms: Tuple[Transform, ...]
    beta: Optional[Beta] = None
    easing: Optional[str] = None

    @classmethod
    def from_proto(cls, k: Any) -> "Keyframe":
        return cls(time_s=float(k.time_s),
                   transforms=tuple(Transform.from_proto(t) for t in k.transforms),
                   beta=Beta.from_proto(k.beta) if k.HasField("beta") else None,
                   easing=(_EASING_NAMES.get(k.easing, f"easing_{int(k.easing)}")
                           if k.HasField("easing") else None))


@dataclass(frozen=True)
class Timeline:
    """A session's timeline. keys: the Keyframes (empty: no timeline); easing: "linear" or
    "smoothstep"; version: the session version it was set at (0: never set); author and
    client_id: who set it."""
    keys: Tuple[Keyframe, ...]
    easing: str
    version: int
    author: str
    client_id: str

    @classmethod
    def from_proto(cls, t: Any) -> "Timeline":
        return cls(keys=tuple(Keyframe.from_proto(k) for k in t.keys),
                   easing=_EASING_NAMES.get(t.easing, f"easing_{int(t.easing)}"),
                   version=int(t.version), author=str(t.author), client_id=str(t.client_id))


@dataclass(frozen=True)
class Snapshot:
    """A named snapshot of a session (hdeform.v1.NamedSnapshot). name; author;
    time_unix_ms; version: the session version it was taken at; beta; transforms: one
    hdeform.Transform per handle; handle_count. `proto`: the message itself (its
    `snapshot.constraints` hold the regions as sent)."""
    name: str
    author: str
    time_unix_ms: int
    version: int
    beta: Beta
    transforms: Tuple[Transform, ...]
    handle_count: int
    proto: Any = field(repr=False, compare=False, default=None)

    @classmethod
    def from_proto(cls, s: Any) -> "Snapshot":
        return cls(name=str(s.name), author=str(s.author), time_unix_ms=int(s.time_unix_ms),
                   version=int(s.version), beta=Beta.from_proto(s.snapshot.beta),
                   transforms=tuple(Transform.from_proto(t) for t in s.snapshot.transforms),
                   handle_count=len(s.snapshot.constraints.handles), proto=s)


@dataclass(frozen=True)
class RigPoseError:
    """How far a rig's linear blend skinning (LBS) is from the exact deformation at one pose
    (hdeform.v1.RigPoseError): per-vertex distances in units of the rest bounding box's
    diagonal. current: the session's current pose (the joints' node transforms), else the
    timeline key at time_s (None for the current pose); max; rms: root mean square over the
    vertices."""
    current: bool
    time_s: Optional[float]
    max: float
    rms: float

    @classmethod
    def from_proto(cls, p: Any) -> "RigPoseError":
        return cls(current=bool(p.current), time_s=None if p.current else float(p.time_s),
                   max=float(p.max), rms=float(p.rms))


@dataclass(frozen=True)
class RigExport:
    """A session's rig (Session.export_rig): glb, the skinned GLB file's bytes (the fixed
    region as root joint 0, handle j as joint j + 1, the harmonic fields as skin weights, the
    timeline's keys as a skeletal animation); joints: 1 + handles; influences: joints per
    vertex (4 or 8); bbox_diagonal: the rest bounding box's diagonal in model units (the
    errors' unit); version: the session version the rig was made at; poses: the LBS error of
    the current pose first, then of each animation key (docs/rig.md)."""
    glb: bytes = field(repr=False)
    joints: int
    influences: int
    bbox_diagonal: float
    version: int
    poses: Tuple[RigPoseError, ...]

    @classmethod
    def from_proto(cls, glb: bytes, r: Any) -> "RigExport":
        return cls(glb=glb, joints=int(r.joints), influences=int(r.influences),
                   bbox_diagonal=float(r.bbox_diagonal), version=int(r.version),
                   poses=tuple(RigPoseError.from_proto(p) for p in r.poses))

    def to_csv(self, path: Optional[Union[str, "os.PathLike[str]"]] = None) -> Optional[str]:
        """The poses as `hdeform rig --report` writes them: the header pose,time_s,max,rms,
        then `current,,MAX,RMS` and one `key,T,MAX,RMS` per key, numbers in their shortest
        round-trip form as the CLI writes them; written to `path`, or returned as a string
        without one."""
        from ._client import _shortest  # the CLI's number format (std::to_chars)
        lines = ["pose,time_s,max,rms"]
        for p in self.poses:
            time_s = "" if p.current or p.time_s is None else _shortest(p.time_s)
            lines.append(",".join(["current" if p.current else "key", time_s,
                                   _shortest(p.max), _shortest(p.rms)]))
        return csv_text(lines, path)


@dataclass(frozen=True)
class RepairReport:
    """What the server's repair of an upload changed (hdeform.v1.MeshRepairReport; docs/api.md
    "Repair"): merged_vertices (merged into a coincident vertex), degenerate_triangles and
    duplicate_triangles (dropped), unreferenced_vertices (dropped: no triangle uses them),
    split_vertices (bowtie vertices split) and added_vertices (the copies the splits added);
    lines: one readable line per kind of change, with the first ids; base_to_input: for each
    frame (base-GLB) vertex the upload's vertex id (read-only int64 array) when the repair
    renumbered the vertices (a split or a dropped vertex), else None (the upload's ids)."""
    merged_vertices: int = 0
    degenerate_triangles: int = 0
    duplicate_triangles: int = 0
    unreferenced_vertices: int = 0
    split_vertices: int = 0
    added_vertices: int = 0
    lines: Tuple[str, ...] = ()
    base_to_input: Optional[npt.NDArray[np.int64]] = field(default=None, compare=False)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, RepairReport):
            return NotImplemented
        a, b = self.base_to_input, other.base_to_input
        return (self._counts() == other._counts() and
                ((a is None and b is None) or
                 (a is not None and b is not None and np.array_equal(a, b))))

    def _counts(self) -> Tuple[Any, ...]:
        return (self.merged_vertices, self.degenerate_triangles, self.duplicate_triangles,
                self.unreferenced_vertices, self.split_vertices, self.added_vertices,
                self.lines)

    @property
    def changed(self) -> bool:
        """Whether the repair changed anything (False: the mesh needed none)."""
        return any(self._counts()[:6])

    @classmethod
    def from_proto(cls, r: Any) -> "RepairReport":
        ids: Optional[npt.NDArray[np.int64]] = None
        if len(r.base_to_input):
            ids = np.asarray(r.base_to_input, dtype=np.int64)
            ids.setflags(write=False)
        return cls(merged_vertices=int(r.merged_vertices),
                   degenerate_triangles=int(r.degenerate_triangles),
                   duplicate_triangles=int(r.duplicate_triangles),
                   unreferenced_vertices=int(r.unreferenced_vertices),
                   split_vertices=int(r.split_vertices), added_vertices=int(r.added_vertices),
                   lines=tuple(str(line) for line in r.lines), base_to_input=ids)
