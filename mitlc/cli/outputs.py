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
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

from mitlc.errors import InputError
from mitlc.fileio import atomic_write

__all__ = ["OutputSet", "MANIFEST", "LOCK", "read_manifest"]

MANIFEST = "manifest.json"
LOCK = ".mitlc.lock"


def read_manifest(out: Path) -> dict | None:
    """The manifest of ``out``, or None when there is none (or it cannot be read)."""
    try:
        data = json.loads((Path(out) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class OutputSet:
    """One training's output folder: locked, checkpointed, written as a set."""

    def __init__(self, out: str | Path, option: str = "--out") -> None:
        self.out = Path(out)
        self.option = option
        self._locked = False

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
        return self

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
        self._manifest("checkpoint", {name: data}, info, earlier=earlier)

    # ------------------------------------------------------------ after
    def write(self, files: Mapping[str, bytes | str], first: str | None = None, **info: object) -> Path:
        """Write the set (``first``, the checkpoint, before the others); the folder written to.

        On a write failure the set goes to a fallback folder instead and an
        :class:`InputError` says where; the files are all in memory, so nothing
        computed is lost.
        """
        payload = {k: v.encode("utf-8") if isinstance(v, str) else v for k, v in files.items()}
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
                OutputSet(fallback)._write_into(fallback, payload, order, info)
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
            atomic_write(out / name, payload[name])
        for name in earlier:  # an earlier set's files this one does not have (only those it listed)
            if name not in payload:
                (out / name).unlink(missing_ok=True)
        self._manifest("complete", payload, info, out)

    def _manifest(
        self,
        state: str,
        files: Mapping[str, bytes],
        info: Mapping,
        out: Path | None = None,
        earlier: list[str] | None = None,
    ) -> None:
        doc: dict = {"state": state, **info}
        doc["files"] = {k: hashlib.sha256(v).hexdigest() for k, v in sorted(files.items())}
        if earlier:
            doc["earlier"] = earlier
        atomic_write((out or self.out) / MANIFEST, json.dumps(doc, indent=1) + "\n")


def _earlier(manifest: dict | None) -> list[str]:
    """The files an earlier set wrote (its own and those it still owed a clean-up), plain names only."""
    if manifest is None:
        return []
    names = [*manifest.get("files", {}), *manifest.get("earlier", [])]
    return sorted(
        {n for n in names if isinstance(n, str) and n and "/" not in n and not n.startswith(".")} - {MANIFEST}
    )
