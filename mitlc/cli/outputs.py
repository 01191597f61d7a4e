"""The files a training writes into ``--out``, kept as one consistent set.

* **Before training**, :meth:`OutputSet.open` creates the folder and takes its lock
  (``fcntl.flock`` on ``.mitlc.lock``, held until :meth:`OutputSet.close`; the file says
  who holds it), writing the holder's pid into it: a folder that cannot be written (a
  full disk, read-only) fails there, before any work, and leaves nothing behind. Two
  trainings never write into one folder at once; a dead process holds no lock. Temporary
  files a killed mitlc left there (``.NAME.PID-XXXXXXXX.mitlc-tmp``) are removed.
* **While training**, :meth:`OutputSet.checkpoint` replaces ``params.npz`` (the
  resume checkpoint) every so often, so a kill -9 loses at most that much.
* **After training**, :meth:`OutputSet.write` writes the whole set as one change: every
  new file is first written beside its target (a temporary file, on disk), then the
  manifest says ``"state": "writing"``, the files are renamed over their targets, an
  earlier set's files the new one does not have (a ``rollout.png`` before ``--no-plots``)
  are removed, and the manifest is replaced by one saying ``"state": "complete"`` with
  each file's SHA-256. When any step fails (a full disk, an immutable file) every file
  already changed is put back as it was (kept as a hard link until the end), so the
  folder holds the earlier set, whole, and the new one goes to a fallback folder that
  the error names. A checkpoint is the same change with ``"state": "checkpoint"``.

The manifest is recognisably mitlc's (``"format": "mitlc-run"``, ``"version": 1``) and names
the spec trained (``spec``, ``spec_sha256``). :meth:`OutputSet.open` refuses a folder that holds
anything but mitlc's own set (files without such a manifest are the user's: never cleaned,
never overwritten), and a folder holding a training of another spec (a re-run of the same spec
replaces its set). mitlc only ever removes names it writes itself (:data:`OWNED`, ``plants/NAME.py``),
whatever a manifest lists. Without ``--out`` a training gets a new folder ``runs/<spec>_<N>``
(:meth:`OutputSet.numbered`), as Stable-Baselines3 and TensorBoard number their runs.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import tempfile
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from mitlc.errors import InputError
from mitlc.fileio import (
    FolderLock,
    LockBusy,
    clean_stale_temps,
    lock_owner_pid,
    missing_folders,
    remove_folders,
    stage,
    temp_path,
)

__all__ = ["OutputSet", "MANIFEST", "LOCK", "FORMAT", "VERSION", "OWNED", "owned", "read_manifest", "spec_record"]

MANIFEST = "manifest.json"
LOCK = ".mitlc.lock"
FORMAT = "mitlc-run"
VERSION = 1
"""The ``format`` and ``version`` keys that make a ``manifest.json`` mitlc's own."""

OWNED = frozenset({"params.npz", "search.npz", "metrics.json", "rollout.png", "learning_curve.png"})
"""The files a training writes into its folder, besides ``manifest.json``, a plant file's copy
``plants/NAME.py`` and a SAC training's models ``sac_NNN.zip``: the only names mitlc ever removes
there (tests/test_writing.py keeps this list in step with what ``mitlc train`` writes: SACPN's
checkpoint ``params.npz``, the policy search's ``search.npz``)."""

_PLANT_COPY = re.compile(r"plants/[A-Za-z0-9_][A-Za-z0-9_.-]*\.py")
_SAC_MODEL = re.compile(r"sac_[0-9]{3,}\.zip")
_MANIFEST_LIMIT = 1 << 24
"""A manifest is a few hundred bytes; a ``manifest.json`` larger than 16 MiB is not mitlc's."""


def owned(name: object) -> bool:
    """Whether ``name`` (relative to a training folder) is a file mitlc writes there."""
    return isinstance(name, str) and (
        name in OWNED or _PLANT_COPY.fullmatch(name) is not None or _SAC_MODEL.fullmatch(name) is not None
    )


def read_manifest(out: Path) -> dict | None:
    """mitlc's manifest of ``out``, or None when there is none, it cannot be read, or it is not
    mitlc's: no ``"format": "mitlc-run"``, or it lists a file mitlc does not write (a user's file
    of that name is theirs, and no manifest makes another file mitlc's)."""
    path = Path(out) / MANIFEST
    try:
        if path.stat().st_size > _MANIFEST_LIMIT:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT or not isinstance(data.get("version"), int):
        return None
    files, owed = data.get("files", {}), data.get("earlier", [])
    if not isinstance(files, dict) or not isinstance(owed, list) or not all(map(owned, [*files, *owed])):
        return None
    return data


def spec_record(spec: object) -> dict[str, str]:
    """What a manifest says of the spec trained: its file (or name) and the SHA-256 of its text."""
    source = getattr(spec, "source", None) or ""
    return {
        "spec": str(getattr(spec, "path", None) or "<spec>"),
        "spec_sha256": hashlib.sha256(source.encode("utf-8")).hexdigest(),
    }


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
        self._lock_file: FolderLock | None = None
        self._made: list[Path] = []
        """Folders this set created (innermost first): removed again when :meth:`open` fails."""
        self._created: list[Path] = []
        """The same once open: removed at :meth:`close` if they are still empty."""

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
        made = missing_folders(parent)
        while True:
            out = parent / f"{stem}_{n}"
            try:
                out.mkdir(parents=True)
            except FileExistsError:
                n += 1
                continue
            except OSError as exc:
                remove_folders(made)
                raise InputError(
                    f"cannot create the output folder {out}: {exc.strerror or exc}", file="--out"
                ) from None
            outset = cls(out, record=record, keep=keep)
            outset._made = [out, *made]
            return outset

    # ------------------------------------------------------------ before
    def open(self) -> OutputSet:
        out = self.out
        for parent in [out, *out.parents]:
            if parent.exists() and not parent.is_dir():
                raise InputError(f"cannot create the output folder {out}: {parent} is a file", file=self.option)
        made = missing_folders(out)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            remove_folders(made)
            raise InputError(f"cannot write into {out}: {exc.strerror or exc}", file=self.option) from None
        self._made = [*made, *self._made]
        try:
            self._lock()  # its pid written and on disk: the probe that the folder takes a file
            self._check_ours()
        except BaseException:
            self.close()
            remove_folders(self._made)
            raise
        self._created, self._made = self._made, []
        before = time.time() - 60  # a temporary file last written a minute before the lock is nobody's
        clean_stale_temps(out, before, legacy={*OWNED, MANIFEST})
        if (out / "plants").is_dir():
            clean_stale_temps(out / "plants", before)
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
        """Take the folder's lock (see :class:`mitlc.fileio.FolderLock`), or say who holds it."""
        lock = FolderLock(self.out / LOCK)
        try:
            lock.acquire()
        except LockBusy as busy:
            pid = lock_owner_pid(busy.owner)
            who = f"another mitlc (pid {pid})" if pid is not None else "another mitlc"
            raise InputError(
                f"{who} is writing into {self.out}: wait for it, or give another folder", file=self.option
            ) from None
        except OSError as exc:
            raise InputError(f"cannot write into {self.out}: {exc.strerror or exc}", file=self.option) from None
        self._lock_file = lock

    def close(self) -> None:
        """Let go of the folder; a folder this set created and nothing was written into (a failed
        write went to the fallback folder) goes too."""
        if self._lock_file is not None:
            self._lock_file.release()
            self._lock_file = None
        remove_folders(self._created)
        self._created = []

    def __enter__(self) -> OutputSet:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------ during
    def checkpoint(self, name: str, data: bytes, **info: object) -> None:
        """Replace the checkpoint file ``name`` (and the kept files); the manifest says the set is a
        checkpoint. On a failure (an :class:`OSError`) the folder is as it was."""
        earlier = _earlier(read_manifest(self.out))
        files = {name: data, **self.keep}
        writing = self._doc("writing", {}, info, sorted({*earlier, *files}))
        final = self._doc("checkpoint", files, info, [n for n in earlier if n not in files])
        _replace_set(self.out, files, [name, *sorted(self.keep)], [], writing, final)

    # ------------------------------------------------------------ after
    def write(self, files: Mapping[str, bytes | str], first: str | None = None, **info: object) -> Path:
        """Write the set (``first``, the checkpoint, before the others); the folder written to.

        On a write failure the folder keeps its earlier set, whole, the set goes to a fallback
        folder instead and an :class:`InputError` says where; the files are all in memory, so
        nothing computed is lost.
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
        remove = [n for n in earlier if n not in payload]  # an earlier set's files this one lacks
        writing = self._doc("writing", {}, info, sorted({*earlier, *payload}))
        final = self._doc("complete", payload, info, [])
        _replace_set(out, payload, order, remove, writing, final)
        if any("/" in n for n in remove):  # plants/NAME.py: its folder goes when it is empty
            try:
                (out / "plants").rmdir()
            except OSError:
                pass

    def _doc(self, state: str, files: Mapping[str, bytes], info: Mapping, earlier: Sequence[str]) -> bytes:
        doc: dict = {"format": FORMAT, "version": VERSION, "state": state, **self.record, **info}
        doc["files"] = {k: hashlib.sha256(v).hexdigest() for k, v in sorted(files.items())}
        if earlier:
            doc["earlier"] = list(earlier)
        return (json.dumps(doc, indent=1) + "\n").encode("utf-8")


def _mode_of(target: Path) -> int | None:
    try:
        st = os.lstat(target)
    except OSError:
        return None
    return stat.S_IMODE(st.st_mode) if stat.S_ISREG(st.st_mode) else None


def _backup(target: Path) -> Path | None:
    """What ``target`` holds now, kept under a temporary name (a hard link, else a copy) until the
    change is done; None when there is no such file."""
    try:
        st = os.lstat(target)
    except FileNotFoundError:
        return None
    if stat.S_ISDIR(st.st_mode):
        return None  # a folder of that name: the rename over it fails, and nothing is changed
    keep = temp_path(target)
    try:
        os.link(target, keep, follow_symlinks=False)  # a symlink is kept as the link it is
    except OSError:  # no hard links here (or an immutable file): a copy
        if not stat.S_ISREG(st.st_mode):
            raise
        return stage(target, target.read_bytes(), stat.S_IMODE(st.st_mode))
    return keep


def _replace_set(
    out: Path,
    files: Mapping[str, bytes],
    order: Sequence[str],
    remove: Sequence[str],
    writing: bytes,
    final: bytes,
) -> None:
    """Replace ``files`` in ``out`` (in ``order``) and remove ``remove``, as one change: the manifest
    ``writing`` first, ``final`` last. Any failure (an :class:`OSError`, or an interrupt) puts every
    file back as it was and removes every temporary file before it is raised again."""
    staged: dict[str, Path] = {}
    kept: dict[str, Path | None] = {}
    changed: list[str] = []
    made: list[Path] = []
    try:
        for name in order:  # 1. the new files, each beside its target and on disk
            target = out / name
            if "/" in name and not target.parent.is_dir():
                target.parent.mkdir()
                made.insert(0, target.parent)
            staged[name] = stage(target, files[name], _mode_of(target))
        staged[" writing"] = stage(out / MANIFEST, writing, _mode_of(out / MANIFEST))
        staged[" final"] = stage(out / MANIFEST, final, _mode_of(out / MANIFEST))
        for name in dict.fromkeys([MANIFEST, *order, *remove]):  # 2. what is there now, kept
            kept[name] = _backup(out / name)
        os.replace(staged[" writing"], out / MANIFEST)  # 3. the change
        del staged[" writing"]
        changed.append(MANIFEST)
        for name in order:
            os.replace(staged[name], out / name)
            del staged[name]
            changed.append(name)
        for name in remove:
            if kept.get(name) is not None:
                os.unlink(out / name)
                changed.append(name)
        os.replace(staged[" final"], out / MANIFEST)
        del staged[" final"]
    except BaseException:
        for name in reversed(changed):  # put back what was there
            try:
                before = kept.pop(name, None)
                if before is not None:
                    os.replace(before, out / name)
                else:
                    os.unlink(out / name)
            except OSError:
                pass
        for tmp in [*staged.values(), *(k for k in kept.values() if k is not None)]:
            _unlink_quietly(tmp)
        remove_folders(made)
        raise
    for k in kept.values():
        if k is not None:
            _unlink_quietly(k)


def _unlink_quietly(path: Path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _earlier(manifest: dict | None) -> list[str]:
    """The files an earlier set wrote (its own and those it still owed a clean-up), only names
    mitlc itself writes (:func:`owned`): a manifest never makes another file mitlc's to remove."""
    if manifest is None:
        return []
    files = manifest.get("files", {})
    owed = manifest.get("earlier", [])
    names = [*(files if isinstance(files, dict) else []), *(owed if isinstance(owed, list) else [])]
    return sorted({n for n in names if owned(n)})
