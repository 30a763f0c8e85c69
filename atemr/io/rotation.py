"""Files written in rotated parts and pruned by count: the one rule the recording and the old trace writer share.

A part ``index`` of ``name.ext`` is the name itself, then ``name.1.ext``, ``name.2.ext``, ...; `prune_oldest`
keeps the newest ``max_files`` of a directory's files matching a pattern, counting the writer's own parts as the
newest and never deleting the part being written.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

log = logging.getLogger(__name__)


def part_path(base: Path, index: int) -> Path:
    """Part ``index`` of a rotated file: ``base`` itself, then ``name.1.ext``, ``name.2.ext``, ..."""
    if index == 0:
        return base
    return base.with_name(f"{base.stem}.{index}{base.suffix}")


def files_by_age(directory: Path, pattern: str) -> list[Path]:
    """The files of ``directory`` matching ``pattern``, oldest first (by modification time, then name)."""
    if not directory.is_dir():
        return []
    files = [p for p in directory.glob(pattern) if p.is_file()]
    return sorted(files, key=lambda p: (p.stat().st_mtime_ns, p.name))


def prune_oldest(directory: Path, pattern: str, max_files: int, parts: Sequence[Path]) -> None:
    """Delete the oldest files matching ``pattern`` beyond ``max_files``; ``parts`` (a writer's own, the last one
    open) count as the newest and the last is never deleted. A file that cannot be deleted is logged."""
    mine = [p for p in parts if p.exists()]
    files = [p for p in files_by_age(directory, pattern) if p not in mine] + mine
    for old in files[: max(0, len(files) - max_files)]:
        if parts and old == parts[-1]:
            continue
        try:
            old.unlink()
        except OSError as exc:
            log.warning("cannot delete the old file %s: %s", old, exc.strerror)
