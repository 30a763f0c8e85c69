"""The documentation lives in the repository and its references hold.

A reader follows a link or a ``docs/<page>.md#<section>`` named in a docstring and must land on the text it
promised; the old design brief outside the repository was cited twenty times after it stopped being
there. So: no tracked file cites that brief, every docs page (and heading) a tracked file names exists,
and every relative link in README.md and docs/*.md resolves to a file of the repository (and to a heading,
when it names one).
"""

from __future__ import annotations

import re
import subprocess
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: A citation of the design brief that is not in the repository, by file name or by section sign.
OUTSIDE_BRIEF = re.compile("DESIGN" + r"(\.md|\s*§)")
#: A docs page named from anywhere in the repository, with its anchor if any.
DOCS_REFERENCE = re.compile(r"(?<![\w/.-])docs/[\w./-]*?\.md(?:#[\w-]+)?")
#: A Markdown inline link or image: [text](target) or ![alt](target).
MARKDOWN_LINK = re.compile(r"!?\[[^\]\n]*\]\(([^()\s]+)\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def tracked_text_files() -> list[Path]:
    """The files git tracks or would add (untracked but not ignored), as text; binary files are skipped."""
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout.splitlines()
    files = []
    for name in listed:
        path = ROOT / name
        if path.is_file() and b"\0" not in path.read_bytes()[:8192]:
            files.append(path)
    return files


def prose_lines(text: str) -> Iterable[tuple[int, str]]:
    """The lines of a Markdown text outside fenced code blocks, numbered from 1."""
    fenced = False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            yield number, line


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: inline code and link marks dropped, lower case, punctuation removed,
    spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = text.replace("`", "").strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """Every heading anchor of a Markdown page (a repeated heading gets -1, -2, ... as on GitHub)."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    for _, line in prose_lines(page.read_text(encoding="utf-8")):
        match = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if match:
            base = slug(match.group(1))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f"{base}-{count}")
    return found


def link_problem(source: Path, target: str, root: Path) -> str | None:
    """Why a relative link from ``source`` does not resolve inside ``root``, or None when it does."""
    if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto: ... are not files of ours
        return None
    path_part, _, anchor = target.partition("#")
    destination = (source.parent / path_part).resolve() if path_part else source.resolve()
    if not destination.is_relative_to(root.resolve()):
        return f"{target} leaves the repository"
    if not destination.exists():
        return f"{target}: no such file"
    if anchor and destination.suffix == ".md" and anchor not in anchors(destination):
        return f"{target}: no heading #{anchor} in {destination.relative_to(root.resolve())}"
    return None


def broken_links(pages: Iterable[Path], root: Path) -> list[str]:
    """Every relative link of these Markdown pages that does not resolve, as ``page:line: why``."""
    problems = []
    for page in pages:
        for number, line in prose_lines(page.read_text(encoding="utf-8")):
            for target in MARKDOWN_LINK.findall(re.sub(r"`[^`]*`", "", line)):
                problem = link_problem(page, target, root)
                if problem:
                    problems.append(f"{page.relative_to(root)}:{number}: {problem}")
    return problems


def documentation_pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "benchmarks" / "README.md"]


def test_no_file_cites_the_design_brief_outside_the_repository() -> None:
    citations = [f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
                 for path in tracked_text_files()
                 for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1)
                 if OUTSIDE_BRIEF.search(line)]
    assert citations == [], "cite the docs/ page that holds it instead:\n" + "\n".join(citations)


def test_every_docs_reference_names_a_page_and_heading_that_exist() -> None:
    problems = []
    for path in tracked_text_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for number, line in enumerate(text.splitlines(), 1):
            for reference in DOCS_REFERENCE.findall(line):
                problem = link_problem(ROOT / "README.md", reference, ROOT)
                if problem:
                    problems.append(f"{path.relative_to(ROOT)}:{number}: {problem}")
    assert problems == [], "\n".join(problems)


def test_every_relative_link_in_the_documentation_resolves() -> None:
    assert (ROOT / "docs" / "README.md").is_file()
    assert broken_links(documentation_pages(), ROOT) == []


def test_every_docs_page_is_listed_in_the_index() -> None:
    index = (ROOT / "docs" / "README.md").read_text(encoding="utf-8")
    listed = {Path(target.partition("#")[0]).name for target in MARKDOWN_LINK.findall(index)}
    unlisted = [page.name for page in sorted((ROOT / "docs").glob("*.md"))
                if page.name != "README.md" and page.name not in listed]
    assert unlisted == []


def test_the_checks_find_a_broken_file_a_broken_anchor_and_a_link_out_of_the_repository(tmp_path: Path) -> None:
    (tmp_path / "pages").mkdir()
    (tmp_path / "pages" / "page.md").write_text("# A page\n\n## The `0x150` frame (power)\n\n## Notes\n## Notes\n")
    readme = tmp_path / "README.md"
    readme.write_text(
        "[ok](pages/page.md#the-0x150-frame-power) [ok](pages/page.md#notes-1) [web](https://example.org/x)\n"
        "[gone](pages/missing.md) [no heading](pages/page.md#nowhere) [outside](../elsewhere/brief.md)\n"
        "```\n[in code](pages/missing.md)\n```\n`[in inline code](pages/missing.md)`\n"
    )
    problems = broken_links([readme], tmp_path)
    assert problems == [
        "README.md:2: pages/missing.md: no such file",
        "README.md:2: pages/page.md#nowhere: no heading #nowhere in pages/page.md",
        "README.md:2: ../elsewhere/brief.md leaves the repository",
    ]
    brief = "DESIGN"  # spelt apart, or this file would cite it
    assert OUTSIDE_BRIEF.search(f"see {brief} §4") and OUTSIDE_BRIEF.search(f"({brief}.md)")
    assert not OUTSIDE_BRIEF.search(f"the {brief} of the layers")
    assert DOCS_REFERENCE.findall("(docs/can.md#heartbeat-and-power, thesis 3.6) and ../docs/x.md") == [
        "docs/can.md#heartbeat-and-power"]
