#!/usr/bin/env python3
"""Checks magvine's documentation: the README's size, relative links and images, and #fragment anchors.

Usage: python3 tools/check_docs.py [REPO_ROOT]     (default: the folder above tools/)

Checks
  (a) README.md is at most 16,384 bytes;
  (b) every relative Markdown link and image in README.md, docs/*.md and phantoms/README.md resolves to an
      existing file or folder;
  (c) every link with a #fragment into a Markdown file (or a pure #fragment into the same file) names a heading
      that exists there, with GitHub's anchor rules: lower case; inline code and link markup reduced to their text;
      characters other than letters, marks, decimal digits, '_', '-' and spaces removed (so Ø is kept, × and ² are
      removed); spaces turned into hyphens; repeated headings get -1, -2, ... suffixes;
  (d) docs/ holds at least 5 Markdown pages.
External links (http, https, mailto and other schemes) are not fetched. Prints one line per problem
(file:line: what) and exits 1 if there is any, else prints a one-line summary and exits 0. Standard library only.
"""

from __future__ import annotations

import os
import re
import sys
import unicodedata
from pathlib import Path
from urllib.parse import unquote

README_LIMIT = 16384  # bytes: the front page stays short (DESIGN.md)
MIN_DOCS_PAGES = 5

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
ATX = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
SETEXT = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
HTML_ANCHOR = re.compile(r"<a\s+[^>]*?(?:name|id)\s*=\s*[\"']([^\"']+)[\"']", re.IGNORECASE)
CODE_SPAN = re.compile(r"(`+)(.+?)\1", re.DOTALL)
# Inline links and images: [text](target "title") / ![alt](target). The text may hold one level of brackets
# (an image inside a link); the target may be <...> or a run without spaces, with balanced parentheses.
INLINE_LINK = re.compile(
    r"(!?)\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\(\s*(<[^>]*>|(?:[^()\s]|\([^()\s]*\))*)(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)"
)
REF_DEF = re.compile(r"^ {0,3}\[([^\]]+)\]:\s*(<[^>]*>|\S+)")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def github_slug(text: str) -> str:
    """The anchor GitHub gives a heading's rendered text (github-slugger's rules, without the duplicate suffix)."""
    out = []
    for ch in text.lower():
        if ch == " ":
            out.append("-")
        elif ch in "-_":
            out.append(ch)
        else:
            cat = unicodedata.category(ch)
            if cat[0] in "LM" or cat in ("Nd", "Nl", "Pc"):
                out.append(ch)
    return "".join(out)


def heading_text(raw: str) -> str:
    """The plain text of a heading's Markdown: code spans keep their content, links and images their text, tags go."""
    spans: list[str] = []

    def keep_code(m: re.Match[str]) -> str:
        spans.append(m.group(2).strip() if m.group(2).strip() else m.group(2))
        return f"\0{len(spans) - 1}\0"

    text = CODE_SPAN.sub(keep_code, raw)
    text = re.sub(r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"!?\[([^\]]*)\]\[[^\]]*\]", r"\1", text)  # reference links
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    # Underscore emphasis only at word boundaries (snake_case stays); asterisks are punctuation and go anyway.
    text = re.sub(r"(?<![0-9A-Za-z])(_{1,3})(\S(?:.*?\S)?)\1(?![0-9A-Za-z])", r"\2", text)
    text = re.sub(r"\\(.)", r"\1", text)  # backslash escapes
    return re.sub(r"\0(\d+)\0", lambda m: spans[int(m.group(1))], text).strip()


def strip_code_spans(line: str) -> str:
    """The line with inline code replaced by spaces (links inside code are not links)."""
    return CODE_SPAN.sub(lambda m: " " * len(m.group(0)), line)


class Page:
    """One Markdown file: its anchors and its links (target, line)."""

    def __init__(self, path: Path):
        self.path = path
        self.anchors: set[str] = set()
        self.links: list[tuple[str, int, bool]] = []  # (target, line number, is image)
        self._read()

    def _read(self) -> None:
        lines = self.path.read_text(encoding="utf-8").splitlines()
        counts: dict[str, int] = {}

        def add_heading(raw: str) -> None:
            base = github_slug(heading_text(raw))
            slug = base
            n = counts.get(base, 0)
            while slug in self.anchors:
                n += 1
                slug = f"{base}-{n}"
            counts[base] = n
            self.anchors.add(slug)

        fence: str | None = None
        previous = ""
        previous_is_paragraph = False
        for number, line in enumerate(lines, start=1):
            m = FENCE.match(line)
            if fence is not None:
                if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence) and not line.strip()[len(m.group(1)):].strip():
                    fence = None
                previous_is_paragraph = False
                continue
            if m:
                fence = m.group(1)
                previous_is_paragraph = False
                continue
            if line.startswith("    ") and not previous_is_paragraph:
                continue  # an indented code block
            for a in HTML_ANCHOR.findall(line):
                self.anchors.add(a)
            h = ATX.match(line)
            if h:
                add_heading(h.group(2) or "")
                previous_is_paragraph = False
            elif SETEXT.match(line) and previous_is_paragraph and not previous.lstrip().startswith(("|", "-", "*", ">")):
                add_heading(previous)
                previous_is_paragraph = False
            else:
                previous_is_paragraph = bool(line.strip()) and not line.lstrip().startswith("|")
            previous = line
            visible = strip_code_spans(line)
            for lm in INLINE_LINK.finditer(visible):
                target = lm.group(3).strip()
                if target.startswith("<") and target.endswith(">"):
                    target = target[1:-1]
                self.links.append((target, number, lm.group(1) == "!"))
            d = REF_DEF.match(visible)
            if d:
                target = d.group(2)
                if target.startswith("<") and target.endswith(">"):
                    target = target[1:-1]
                self.links.append((target, number, False))


def check(root: Path) -> tuple[list[str], str]:
    problems: list[str] = []
    readme = root / "README.md"
    docs = root / "docs"

    def rel(p: Path) -> str:
        try:
            return p.resolve().relative_to(root.resolve()).as_posix()
        except ValueError:
            return str(p)

    # (a) the front page's size
    if not readme.is_file():
        problems.append("README.md:1: missing")
    else:
        size = readme.stat().st_size
        if size > README_LIMIT:
            problems.append(f"README.md:1: {size} bytes, more than the {README_LIMIT} allowed")

    # (d) the docs set
    pages_in_docs = sorted(docs.glob("*.md")) if docs.is_dir() else []
    if len(pages_in_docs) < MIN_DOCS_PAGES:
        problems.append(f"docs:1: {len(pages_in_docs)} Markdown pages, fewer than {MIN_DOCS_PAGES}")

    files = [p for p in [readme, *pages_in_docs, root / "phantoms" / "README.md"] if p.is_file()]
    cache: dict[Path, Page] = {}

    def page(p: Path) -> Page:
        key = p.resolve()
        if key not in cache:
            cache[key] = Page(p)
        return cache[key]

    links = 0
    for f in files:
        src = page(f)
        for target, line, is_image in src.links:
            where = f"{rel(f)}:{line}"
            kind = "image" if is_image else "link"
            if not target:
                problems.append(f"{where}: empty {kind} target")
                continue
            if SCHEME.match(target) or target.startswith("//"):
                continue  # http(s), mailto, ...: not fetched
            links += 1
            path_part, _, fragment = target.partition("#")
            path_part = path_part.split("?", 1)[0]
            if path_part:
                dest = (root / unquote(path_part).lstrip("/")) if path_part.startswith("/") else (f.parent / unquote(path_part))
                if not dest.exists():
                    problems.append(f"{where}: {kind} to '{target}': {rel(dest)} does not exist")
                    continue
            else:
                dest = f
            if fragment:
                anchor = unquote(fragment)
                if dest.is_file() and dest.suffix.lower() in (".md", ".markdown"):
                    if anchor not in page(dest).anchors and anchor.lower() not in page(dest).anchors:
                        problems.append(f"{where}: {kind} to '{target}': no heading with anchor #{anchor} in {rel(dest)}")
                elif dest.is_dir():
                    problems.append(f"{where}: {kind} to '{target}': a fragment into a folder")
    summary = (
        f"check_docs: OK: README.md {readme.stat().st_size if readme.is_file() else 0} bytes (limit {README_LIMIT}), "
        f"{len(pages_in_docs)} pages in docs/, {links} relative links and images in {len(files)} files resolve"
    )
    return problems, summary


def main(argv: list[str]) -> int:
    if len(argv) > 2 or (len(argv) == 2 and argv[1] in ("-h", "--help")):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    root = Path(argv[1]) if len(argv) == 2 else Path(__file__).resolve().parent.parent
    if not root.is_dir():
        print(f"check_docs: {root}: not a folder", file=sys.stderr)
        return 2
    problems, summary = check(root)
    for p in problems:
        print(p)
    if problems:
        print(f"check_docs: {len(problems)} problem(s)", file=sys.stderr)
        return 1
    print(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
