"""The files a training writes into ``--out``, kept as one consistent set.

* **Before training**, :meth:`OutputSet.open` creates the folder, proves it writable
  (a probe file) and takes its lock (``.mitlc.lock``, created exclusively; a lock
  whose process is gone is taken over), so that a bad ``--out`` fails before any
  work and two trainings never write into one folder at once.
* **While training**, :meth:`OutputSet.checkpoint` replaces ``params.npz`` (the
  resume checkpoint) atomically every so often, so a kill -9 loses at most that
  much.
* **After training**, :meth:`OutputSet.write` writes the whole set: first a
  manifest that says the set is being written, then every file (each atomic),
  then the manifest with each file's SHA-256, written last. A set whose manifest
  says ``"state": "complete"`` and whose files match their hashes is one
  training's; files of an earlier set that the new one does not have (a
  ``rollout.png`` before ``--no-plots``) are removed, and only those the earlier
  manifest lists. When the folder cannot be written any more (a full disk), the
  set goes to a fallback folder and the error says where.

The manifest is recognisably mitlc's (``"format": "mitlc-run"``, ``"version": 1``) and names
the spec trained (``spec``, ``spec_sha256``). :meth:`OutputSet.open` refuses a folder that holds
anything but mitlc's own set (files without such a manifest are the user's: never cleaned,
never overwritten), and a folder holding a training of another spec (a re-run of the same spec
replaces its set). Without ``--out`` a training gets a new folder ``runs/<spec>_<N>``
(:meth:`OutputSet.numbered`), as Stable-Baselines3 and TensorBoard number their runs.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import socket
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

from mitlc.errors import InputError
from mitlc.fileio import atomic_write

__all__ = ["OutputSet", "MANIFEST", "LOCK", "FORMAT", "VERSION", "read_manifest", "spec_record"]

MANIFEST = "manifest.json"
LOCK = ".mitlc.lock"
FORMAT = "mitlc-run"
VERSION = 1
"""The ``format`` and ``version`` keys that make a ``manifest.json`` mitlc's own."""


def read_manifest(out: Path) -> dict | None:
    """mitlc's manifest of ``out``, or None when there is none, it cannot be read, or it is not
    mitlc's (no ``"format": "mitlc-run"``: a user's file of that name is theirs)."""
    try:
        data = json.loads((Path(out) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("version"), int):
        return None
    return data


def spec_record(spec: object) -> dict[str, str]:
    """What a manifest says of the spec trained: its file (or name) and the SHA-256 of its text."""
    source = getattr(spec, "source", None) or ""
    return {
        "spec": str(getattr(spec, "path", None) or "<spec>"),
        "spec_sha256": hashlib.sha256(source.encode("utf-8")).hexdigest(),
    }


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class OutputSet:
    """One training's output folder: locked, checkpointed, written as a set.

    ``record`` goes into every manifest written (the spec trained, its plant); ``keep`` are files
    written with every checkpoint and set (a plant file's copy, ``plants/NAME.py``)."""

    def __init__(
        self,
        out: str | Path,
        option: str = "--out",
        record: Mapping[str, object] | None = None,
        keep: Mapping[str, bytes] | None = None,
        continuing: bool = False,
    ) -> None:
        self.out = Path(out)
        self.option = option
        self.record = dict(record or {})
        self.keep = dict(keep or {})
        self.continuing = continuing
        """The folder's own checkpoint is being continued (``--resume DIR`` into DIR): taken as a
        training even without mitlc's manifest (one written before it had the format key)."""
        self._locked = False

    @classmethod
    def numbered(
        cls,
        parent: str | Path,
        stem: str,
        record: Mapping[str, object] | None = None,
        keep: Mapping[str, bytes] | None = None,
    ) -> OutputSet:
        """A new folder ``parent/<stem>_<N>``, N one more than the highest taken (``p2_avoid_1``,
        ``p2_avoid_2``...), created here so that two trainings starting at once never share one."""
        parent = Path(parent)
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", stem) or "run"
        numbered = re.compile(rf"{re.escape(stem)}_(\d+)")
        try:
            taken = [int(m.group(1)) for p in parent.iterdir() if (m := numbered.fullmatch(p.name))]
        except OSError:
            taken = []
        n = max(taken, default=0) + 1
        for parent_of in [parent, *parent.parents]:
            if parent_of.exists() and not parent_of.is_dir():
                raise InputError(f"cannot create the output folder {parent}: {parent_of} is a file", file="--out")
        while True:
            out = parent / f"{stem}_{n}"
            try:
                out.mkdir(parents=True)
            except FileExistsError:
                n += 1
                continue
            except OSError as exc:
                raise InputError(
                    f"cannot create the output folder {out}: {exc.strerror or exc}", file="--out"
                ) from None
            return cls(out, record=record, keep=keep)

    # ------------------------------------------------------------ before
    def open(self) -> OutputSet:
        out = self.out
        for parent in [out, *out.parents]:
            if parent.exists() and not parent.is_dir():
                raise InputError(f"cannot create the output folder {out}: {parent} is a file", file=self.option)
        try:
            out.mkdir(parents=True, exist_ok=True)
            fd, probe = tempfile.mkstemp(prefix=".probe.", dir=out)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            raise InputError(f"cannot write into {out}: {exc.strerror or exc}", file=self.option) from None
        self._lock()
        try:
            self._check_ours()
        except InputError:
            self.close()
            raise
        return self

    def _check_ours(self) -> None:
        """Refuse a folder that holds the user's files, or a training of another spec."""
        manifest = read_manifest(self.out)
        if manifest is None and self.continuing:
            return
        if manifest is None:
            try:
                theirs = sorted(p.name for p in self.out.iterdir() if not p.name.startswith("."))
            except OSError as exc:
                raise InputError(f"cannot read {self.out}: {exc.strerror or exc}", file=self.option) from None
            if theirs:
                shown = ", ".join(theirs[:3]) + (f" and {len(theirs) - 3} more" if len(theirs) > 3 else "")
                raise InputError(
                    f"{self.out} holds files that are not a mitlc training ({shown}); mitlc writes only into a "
                    "new or empty folder or one of its own trainings: give another --out",
                    file=self.option,
                )
            return
        mine, theirs_sha = self.record.get("spec_sha256"), manifest.get("spec_sha256")
        if mine is not None and theirs_sha is not None and mine != theirs_sha:
            spec = manifest.get("spec")
            what = (
                f"a training of {spec}"
                if isinstance(spec, str) and spec != self.record.get("spec")
                else (
                    f"a training of another text of {spec}" if isinstance(spec, str) else "a training of another spec"
                )
            )
            raise InputError(
                f"{self.out} holds {what}; give another --out, or continue it with mitlc train --resume {self.out}",
                file=self.option,
            )

    def _lock(self) -> None:
        path = self.out / LOCK
        me = f"{os.getpid()} {socket.gethostname()}\n"
        for _ in range(2):
            try:
                fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid_text, host = (path.read_text().split() + ["", ""])[:2]
                    pid = int(pid_text)
                except (OSError, ValueError):
                    pid, host = -1, ""
                if pid > 0 and host == socket.gethostname() and _alive(pid):
                    raise InputError(
                        f"another mitlc (pid {pid}) is writing into {self.out}: wait for it, or give another folder",
                        file=self.option,
                    ) from None
                path.unlink(missing_ok=True)  # its process is gone: a stale lock
                continue
            with os.fdopen(fd, "w") as fh:
                fh.write(me)
            self._locked = True
            return
        raise InputError(f"cannot take the lock {path}", file=self.option)

    def close(self) -> None:
        if self._locked:
            (self.out / LOCK).unlink(missing_ok=True)
            self._locked = False

    def __enter__(self) -> OutputSet:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------ during
    def checkpoint(self, name: str, data: bytes, **info: object) -> None:
        """Replace the checkpoint file ``name``; the manifest says the set is a checkpoint."""
        earlier = _earlier(read_manifest(self.out))
        atomic_write(self.out / name, data)
        for kept, content in self.keep.items():
            _write_file(self.out, kept, content)
        self._manifest("checkpoint", {name: data, **self.keep}, info, earlier=earlier)

    # ------------------------------------------------------------ after
    def write(self, files: Mapping[str, bytes | str], first: str | None = None, **info: object) -> Path:
        """Write the set (``first``, the checkpoint, before the others); the folder written to.

        On a write failure the set goes to a fallback folder instead and an
        :class:`InputError` says where; the files are all in memory, so nothing
        computed is lost.
        """
        payload = {k: v.encode("utf-8") if isinstance(v, str) else v for k, v in files.items()}
        payload.update(self.keep)
        order = sorted(payload, key=lambda k: (k != first, k))
        try:
            self._write_into(self.out, payload, order, info)
            return self.out
        except OSError as exc:
            reason = exc.strerror or str(exc)
        for base in (Path(tempfile.gettempdir()), Path.home(), Path.cwd()):
            fallback = base / f"mitlc-rescue-{self.out.name or 'out'}-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}"
            try:
                fallback.mkdir(parents=True, exist_ok=True)
                OutputSet(fallback, record=self.record)._write_into(fallback, payload, order, info)
            except OSError:
                continue
            raise InputError(
                f"cannot write the results into {self.out} ({reason}); they are saved in {fallback} "
                f"(continue with: mitlc train --resume {fallback})",
                file=self.option,
            )
        raise InputError(f"cannot write the results into {self.out} ({reason}), nor into any fallback folder")

    def _write_into(self, out: Path, payload: Mapping[str, bytes], order: list[str], info: Mapping) -> None:
        earlier = _earlier(read_manifest(out))
        self._manifest("writing", {}, info, out, earlier=earlier)
        for name in order:
            _write_file(out, name, payload[name])
        for name in earlier:  # an earlier set's files this one does not have (only those it listed)
            if name not in payload:
                (out / name).unlink(missing_ok=True)
                if "/" in name:  # plants/NAME.py: its folder goes when it is empty
                    try:
                        (out / name).parent.rmdir()
                    except OSError:
                        pass
        self._manifest("complete", payload, info, out)

    def _manifest(
        self,
        state: str,
        files: Mapping[str, bytes],
        info: Mapping,
        out: Path | None = None,
        earlier: list[str] | None = None,
    ) -> None:
        doc: dict = {"format": FORMAT, "version": VERSION, "state": state, **self.record, **info}
        doc["files"] = {k: hashlib.sha256(v).hexdigest() for k, v in sorted(files.items())}
        if earlier:
            doc["earlier"] = earlier
        atomic_write((out or self.out) / MANIFEST, json.dumps(doc, indent=1) + "\n")


def _write_file(out: Path, name: str, data: bytes) -> None:
    if "/" in name:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out / name, data)


_PLAIN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def _earlier(manifest: dict | None) -> list[str]:
    """The files an earlier set wrote (its own and those it still owed a clean-up): plain names, or
    ``plants/NAME`` (a plant file's copy), nothing else."""
    if manifest is None:
        return []
    files = manifest.get("files", {})
    owed = manifest.get("earlier", [])
    names = [*(files if isinstance(files, dict) else []), *(owed if isinstance(owed, list) else [])]
    ok = {
        n
        for n in names
        if isinstance(n, str)
        and all(_PLAIN.fullmatch(part) for part in n.split("/"))
        and n.count("/") <= 1
        and (n.count("/") == 0 or n.startswith("plants/"))
    }
    return sorted(ok - {MANIFEST})
