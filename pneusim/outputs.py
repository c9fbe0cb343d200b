"""Writing results safely: atomic files, no input overwritten, no results folder of another run mixed in.

Three rules every command that writes follows:

* **atomic files** -- :func:`write_text_atomic`, :func:`write_bytes_atomic`, :func:`write_json_atomic`,
  :func:`savefig_atomic` and, for any other writer, :func:`atomic_path`: the data go to a temporary file
  in the target's folder (same suffix, so writers that read it still work), are flushed to disk, and
  ``os.replace`` puts the file in place.  A crash or a full disk leaves the previous file or none,
  never a truncated one;
* **no input overwritten** -- :func:`refuse_inputs_as_outputs` refuses, before any work, an output path
  that is the same file as one of the command's inputs (``os.path.samefile``, or the resolved path of a
  file not written yet);
* **one run per results folder** -- :class:`ResultsFolder` keeps a manifest (:data:`MANIFEST`) of the
  run that wrote the folder: a digest of everything that determines its results, the command line and
  the files written.  A folder holding the results of a *different* run is refused, or cleared with a
  message (each command chooses, see :class:`ResultsFolder`), so that old reports and figures never
  stand beside new data.  A rerun of the same inputs replaces its own files and removes those it no
  longer writes.
"""

from __future__ import annotations

import contextlib
import fnmatch
import hashlib
import json
import os
import secrets
import shlex
import time
from pathlib import Path
from typing import Iterable, Mapping

from .errors import PneusimError

__all__ = ["atomic_path", "write_bytes_atomic", "write_text_atomic", "write_json_atomic", "savefig_atomic",
           "same_file", "refuse_inputs_as_outputs", "digest", "file_digest", "ResultsFolder", "command_text",
           "MANIFEST", "FOLDER_POLICIES"]

#: the manifest of a results folder (JSON): which run wrote it and which files
MANIFEST = "pneusim-manifest.json"
MANIFEST_FORMAT = "pneusim-manifest/1"
#: ``refuse``: a folder of another run is refused unless ``overwrite`` (then cleared); ``replace``: it is
#: cleared with a message; ``measured``: every earlier run counts as another (measured data are never
#: replaced without ``overwrite``)
FOLDER_POLICIES = ("refuse", "replace", "measured")


# ---------------------------------------------------------------- atomic files
def _temporary_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` that keeps its suffix (``.NAME.TOKEN.tmp.SUFFIX``)."""
    return path.with_name(f".{path.stem}.{secrets.token_hex(4)}.tmp{path.suffix}")


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (best effort: not every file system lets a folder be opened)."""
    try:
        _fsync(folder)
    except OSError:
        pass


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; when the block ends without an exception the file written
    there is flushed to disk and replaces ``path`` (``os.replace``), else it is removed and ``path`` is
    left as it was.

    The temporary name keeps the suffix (``.coefficients.3f9a.tmp.npz``), so writers that choose the
    format by it (``savefig``, ``np.savez``, ``scipy.io.savemat``) write the same bytes.
    """
    path = Path(path)
    tmp = _temporary_name(path)
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_folder(path.parent)


def write_bytes_atomic(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`); returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "xb") as fh:
        fh.write(data)
    return path


def write_text_atomic(path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (no newline translation: ``"\\n"`` stays ``"\\n"``)."""
    return write_bytes_atomic(path, text.encode(encoding))


def write_json_atomic(path, obj, *, trailing_newline: bool = False, **dumps_options) -> Path:
    """``json.dumps(obj, **dumps_options)`` written to ``path`` atomically (a newline after it if asked)."""
    return write_text_atomic(path, json.dumps(obj, **dumps_options) + ("\n" if trailing_newline else ""))


def savefig_atomic(fig, path, **savefig_options) -> Path:
    """``fig.savefig`` into ``path`` atomically; the format is the suffix's, as ``savefig`` would choose."""
    path = Path(path)
    savefig_options.setdefault("format", path.suffix.lstrip(".").lower() or None)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **savefig_options)
    return path


# ---------------------------------------------------------------- inputs are never outputs
def same_file(a, b) -> bool:
    """Whether ``a`` and ``b`` name the same file: ``os.path.samefile`` when both exist (links and other
    spellings of one file included), else the same resolved path."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return Path(a).resolve() == Path(b).resolve()


def refuse_inputs_as_outputs(outputs: Mapping[str, object], inputs: Mapping[str, object]) -> None:
    """Refuse, in one sentence, an output that is one of the inputs.

    Parameters
    ----------
    outputs : mapping
        What names the output (``"--out"``) to its path, or to a list of paths.
    inputs : mapping
        What names the input (``"the recording given with --like"``) to its path (None: no such input).
    """
    for option, paths in outputs.items():
        for out in ([paths] if isinstance(paths, (str, os.PathLike)) else list(paths or ())):
            for what, inp in inputs.items():
                if inp is not None and same_file(out, inp):
                    raise PneusimError(f"{option} {out}: that is {what} ({inp}); a command never writes over "
                                       "its input: give another file name")


# ---------------------------------------------------------------- digests
def digest(obj) -> str:
    """SHA-256 (hex) of ``obj`` as canonical JSON (keys sorted; other types by ``str``)."""
    text = json.dumps(obj, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def file_digest(path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---------------------------------------------------------------- results folders
def _is_temporary(name: str) -> bool:
    return name.startswith(".") and ".tmp" in name


class ResultsFolder:
    """A command's results folder: refused or cleared when it holds another run's results; its manifest.

    Parameters
    ----------
    path : path
        The folder (created by :meth:`prepare`).
    option : str
        The option that named it, for messages (``"--out"``).
    command : str
        The command line that makes this run (kept in the manifest, quoted in messages).
    identity : object or None
        Everything that determines the results (JSON-able; its :func:`digest` is compared).  ``None``
        with policy ``measured``.
    policy : {'refuse', 'replace', 'measured'}
        What to do with a folder that holds another run's results (:data:`FOLDER_POLICIES`).
    overwrite : bool
        With ``refuse`` or ``measured``: clear the other run's files (with a message) instead of refusing.
    known : sequence of str
        Names and glob patterns (relative to the folder) of the files this command writes: an existing
        file of such a name would be replaced, so it counts as another run's; the patterns count where
        the folder is marked as this command's (``markers``).  What is removed when it is cleared.
    markers : sequence of str
        Names whose presence marks a folder without a manifest as one of this command's (default
        ``known``'s plain names).
    keep : sequence of str
        Top-level names never cleared nor listed (a cache keyed on its inputs, e.g. a sweep's ``runs``).
    inputs : mapping
        The command's inputs (what to path), never cleared: clearing one is refused.

    Examples
    --------
    >>> folder = ResultsFolder("results/x", "--out", "pneusim run x.toml", identity=spec)  # doctest: +SKIP
    >>> notes = folder.prepare()          # refuses another run's folder, or clears it
    >>> ...                               # write the results
    >>> folder.finish()                   # the manifest lists them; files of the last run not rewritten go
    """

    def __init__(self, path, option: str, command: str, identity=None, *, policy: str = "refuse",
                 overwrite: bool = False, known: Iterable[str] = (), markers: Iterable[str] | None = None,
                 keep: Iterable[str] = (), inputs: Mapping[str, object] | None = None):
        if policy not in FOLDER_POLICIES:
            raise ValueError(f"policy must be one of {FOLDER_POLICIES}, got {policy!r}")
        self.path = Path(path)
        self.option, self.command, self.policy, self.overwrite = option, command, policy, bool(overwrite)
        self.identity = None if identity is None else digest(identity)
        self.known = tuple(known)
        self.markers = tuple(markers) if markers is not None else tuple(k for k in self.known if "*" not in k)
        self.keep = set(keep) | {MANIFEST}
        self.inputs = dict(inputs or {})
        self.notes: list[str] = []
        self._before: dict[str, tuple] = {}
        self._previous: list[str] = []

    # ------------------------------------------------------------ reading what is there
    def _manifest(self) -> dict | None:
        f = self.path / MANIFEST
        if not f.is_file():
            return None
        try:
            data = json.loads(f.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
        return data if isinstance(data, dict) and data.get("format") == MANIFEST_FORMAT else {}

    def _listing(self) -> dict[str, tuple]:
        """Every file below the folder (relative path -> identity of its contents on disk), but the kept
        names, the manifest and temporary files."""
        out = {}
        for root, dirs, files in os.walk(self.path):
            rel_root = Path(root).relative_to(self.path)
            if rel_root == Path("."):
                dirs[:] = [d for d in dirs if d not in self.keep]
            for name in files:
                rel = (rel_root / name).as_posix()
                if (rel_root == Path(".") and name in self.keep) or _is_temporary(name):
                    continue
                try:
                    st = os.stat(Path(root) / name)
                except OSError:
                    continue
                out[rel] = (st.st_ino, st.st_mtime_ns, st.st_size)
        return out

    def _inside(self, rel: str) -> bool:
        """A manifest's entry names a file inside the folder (never ``../``), not a kept one."""
        try:
            (self.path / rel).resolve().relative_to(self.path.resolve())
        except ValueError:
            return False
        parts = Path(rel).parts
        return bool(parts) and parts[0] not in self.keep

    def _previous_files(self, manifest: dict | None) -> list[str]:
        """The files of another run in the folder: its manifest's list; every file of a name this command
        writes (it would be replaced); and, where the folder is marked as this command's (a manifest, or
        one of its marker files), every file matching the command's patterns (figures, per-case files)."""
        names = set()
        if manifest:
            names |= {rel for rel in manifest.get("files", []) if isinstance(rel, str) and self._inside(rel)}
        listing = self._listing()
        names |= {rel for rel in listing if rel in self.known}
        if manifest is not None or any((self.path / m).exists() for m in self.markers):
            names |= {rel for rel in listing if any(fnmatch.fnmatchcase(rel, k) for k in self.known)}
        return sorted(rel for rel in names if (self.path / rel).is_file())

    # ------------------------------------------------------------ the two steps
    def prepare(self) -> list[str]:
        """Create the folder, refuse it or clear it as the policy says, and mark it as this run's.

        Returns the notes for the user (also in :attr:`notes`), e.g. what was cleared.

        Raises
        ------
        PneusimError
            The folder cannot be created or written; it holds another run's results (policy ``refuse``
            or ``measured`` without ``overwrite``); or one of its results is an input of this run.
        """
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise PneusimError(f"{self.option} {self.path}: the folder cannot be created "
                               f"({exc.strerror or exc})") from None
        if not os.access(self.path, os.W_OK):
            raise PneusimError(f"{self.option} {self.path}: the folder cannot be written")
        manifest = self._manifest()
        previous = self._previous_files(manifest)
        for rel in previous:
            for name, inp in self.inputs.items():
                if inp is not None and same_file(self.path / rel, inp):
                    raise PneusimError(f"{self.option} {self.path}: the folder holds {rel}, {name} of this run, "
                                       "which the results would replace; give another folder")
        same_run = bool(manifest) and self.policy != "measured" and manifest.get("identity") == self.identity
        if previous and not same_run:
            self._clear_other_run(manifest, previous)
            previous = []
        self._previous = previous
        self._before = self._listing()
        self._write_manifest(complete=False, files=previous)
        return self.notes

    def _describe(self, manifest: dict | None, previous: list[str]) -> str:
        if manifest:
            when = manifest.get("finished") or manifest.get("started") or "?"
            state = "" if manifest.get("complete") else ", not finished"
            return f"{manifest.get('command', '?')} ({when}{state})"
        shown = ", ".join(previous[:3]) + (", ..." if len(previous) > 3 else "")
        return f"{shown}; no {MANIFEST}: written by an older pneusim or by hand"

    def _clear_other_run(self, manifest: dict | None, previous: list[str]) -> None:
        what = self._describe(manifest, previous)
        if self.policy != "replace" and not self.overwrite:
            kind = ("an earlier run (measured data are never replaced)" if self.policy == "measured"
                    else "another run")
            raise PneusimError(f"{self.option} {self.path}: the folder holds the results of {kind}: {what}; give "
                               "another folder, or --overwrite to remove those results first")
        removed = self._remove(previous)
        self.notes.append(f"{self.option} {self.path}: removed {removed} file(s) of the results of another run "
                          f"({what})")

    def _remove(self, rels: Iterable[str]) -> int:
        count = 0
        folders = set()
        for rel in rels:
            with contextlib.suppress(FileNotFoundError):
                (self.path / rel).unlink()
                count += 1
            folders |= {self.path / p for p in Path(rel).parents if str(p) != "."}
        for folder in sorted(folders, key=lambda p: len(p.parts), reverse=True):
            with contextlib.suppress(OSError):
                folder.rmdir()       # only when empty: a user's own files stay
        return count

    def finish(self) -> list[str]:
        """List the files this run wrote in the manifest (marked complete) and remove the files of the
        last run of the same inputs that this run did not write again; returns the files written."""
        after = self._listing()
        written = sorted(rel for rel, ident in after.items() if self._before.get(rel) != ident)
        stale = [rel for rel in self._previous if rel not in written]
        if stale:
            self._remove(stale)
        self._write_manifest(complete=True, files=written)
        return written

    def _write_manifest(self, complete: bool, files: list[str]) -> None:
        now = time.strftime("%Y-%m-%d %H:%M:%S")
        started = now
        if complete:
            started = (self._manifest() or {}).get("started", now)
        data = {"format": MANIFEST_FORMAT, "command": self.command, "identity": self.identity,
                "policy": self.policy, "complete": complete, "started": started, "files": list(files)}
        if complete:
            data["finished"] = now
        write_json_atomic(self.path / MANIFEST, data, indent=1, trailing_newline=True)


def command_text(argv: Iterable[str] | None, name: str) -> str:
    """``pneusim NAME ARGS...`` of a parsed command (what made a folder, for its manifest)."""
    return "pneusim " + (shlex.join(list(argv)) if argv else name)

