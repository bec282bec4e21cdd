"""What the fleet job's RECORDINGS stand for: files, directories searched for recordings, or
URIs any pyarrow filesystem opens, as a list of recordings (each one or more files).

An imud session's rotated files (``PREFIX-YYYYMMDDTHHMMSSZ-NNNN.mcap``: the recorder's prefix,
the file's start and its ``file-index``, 0 at each start of imud) are one recording, joined as
:func:`imud.read` joins a session's files; ``group_sessions`` in imu-analysis groups by the same
prefix and consecutive index from the files' metadata, here told from the names the recorder
gives them so the driver reads no file (a task reads each recording once). A rosbag2 directory
(one with ``metadata.yaml``) is one recording; every other file is a recording of its own.
"""

from __future__ import annotations

import os
import posixpath
import re
from dataclasses import dataclass
from typing import Any, List, Optional, Sequence, Tuple

#: Files a directory search takes as recordings (every reader tells the format by content; a
#: directory of mixed files needs a filter, and these are the binary formats imud reads).
RECORDING_SUFFIXES = (".mcap", ".bag", ".db3")

_SESSION_FILE = re.compile(r"^(?P<prefix>.+)-(?P<stamp>\d{8}T\d{6}Z)-(?P<index>\d{4,})\.mcap$")


@dataclass
class RecordingSpec:
    """One recording for a task: its files (on ``filesystem``, local when None) and the name
    it is reported under (its first file, or its rosbag2 directory)."""

    path: str
    files: List[str]
    filesystem: Any = None
    #: Set for a rosbag2 directory: the files keep their names inside one directory.
    directory: Optional[str] = None


def resolve(arg: str, filesystem: Any = None) -> Tuple[Any, str, bool]:
    """(filesystem, path on it, remote?) of a path the fleet job reads or writes: a path on
    ``filesystem`` when one is given, else a URI any pyarrow filesystem opens, else a local path
    (``file://`` or plain, made absolute)."""
    from pyarrow import fs as pafs

    if filesystem is not None:
        return filesystem, arg, not isinstance(filesystem, pafs.LocalFileSystem)
    if "://" in arg and not arg.startswith("file://"):
        f, p = pafs.FileSystem.from_uri(arg)
        return f, p, not isinstance(f, pafs.LocalFileSystem)
    if arg.startswith("file://"):
        arg = arg[len("file://") :]
    return pafs.LocalFileSystem(), os.path.abspath(arg), False


def find_recordings(args: Sequence[Any], filesystem: Any = None) -> List[RecordingSpec]:
    """The recordings ``args`` stand for, in argument order (a directory's in name order).

    Raises FileNotFoundError naming an argument that does not exist, and ValueError for a
    directory holding no recording."""
    from pyarrow import fs as pafs

    out: List[RecordingSpec] = []
    for raw in args:
        arg = os.fspath(raw)
        f, p, remote = resolve(arg, filesystem)
        info = f.get_file_info(p)
        if info.type == pafs.FileType.NotFound:
            raise FileNotFoundError(f"no such recording or directory: {arg}")
        fs_kept = f if remote else None
        # A URI's recordings are reported under their URI (the filesystem's paths drop the scheme).
        scheme = arg.split("://", 1)[0] + "://" if remote and filesystem is None else ""
        if info.type == pafs.FileType.File:
            out += _named(_group([p], fs_kept), scheme)
            continue
        listing = f.get_file_info(pafs.FileSelector(p, recursive=True))
        files = sorted(i.path for i in listing if i.type == pafs.FileType.File)
        bag_dirs = sorted(
            {posixpath.dirname(x) for x in files if posixpath.basename(x) == "metadata.yaml"}
        )
        found: List[RecordingSpec] = []
        for d in bag_dirs:
            inside = [x for x in files if x.startswith(d + "/")]
            found.append(RecordingSpec(path=d, files=inside, filesystem=fs_kept, directory=d))
        loose = [
            x
            for x in files
            if x.lower().endswith(RECORDING_SUFFIXES)
            and not any(x.startswith(d + "/") for d in bag_dirs)
        ]
        found += _group(loose, fs_kept)
        if not found:
            raise ValueError(
                f"{arg}: a directory without recordings (files ending in "
                f"{', '.join(RECORDING_SUFFIXES)}, or rosbag2 directories)"
            )
        out += _named(sorted(found, key=lambda s: s.path), scheme)
    return out


def _named(specs: List[RecordingSpec], scheme: str) -> List[RecordingSpec]:
    for s in specs:
        s.path = scheme + s.path
    return specs


def _group(files: List[str], fs: Any) -> List[RecordingSpec]:
    """Files as recordings: an imud session's consecutive files (same prefix, index one more
    than the last file's) as one, every other file alone; in the order given."""
    out: List[RecordingSpec] = []
    last: dict = {}  # (dir, prefix) -> (spec, last index)
    for x in files:
        m = _SESSION_FILE.match(posixpath.basename(x))
        if m is None:
            out.append(RecordingSpec(path=x, files=[x], filesystem=fs))
            continue
        key = (posixpath.dirname(x), m["prefix"])
        index = int(m["index"])
        prev = last.get(key)
        if prev is not None and index == prev[1] + 1 and index > 0:
            prev[0].files.append(x)
            last[key] = (prev[0], index)
            continue
        spec = RecordingSpec(path=x, files=[x], filesystem=fs)
        out.append(spec)
        last[key] = (spec, index)
    return out
