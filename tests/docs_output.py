"""The output the docs show is the output the commands print: check it, or rewrite it in place.

Convention for the docs: an HTML comment right before a ``text`` block names
the command whose printed output (standard output and standard error, as a
terminal shows them) the block shows::

    <!-- output of: .venv/bin/kinid plan --machine urdf/five_axis_bc.urdf --target-um 0.5 --out plan.csv -->
    ```text
    candidates: 1248 alignments (...)
    ...
    plan written to plan.csv
    ```

- The command is written as in the page's ``sh`` blocks (``kinid …`` stands
  for ``.venv/bin/kinid …``). When the same command ran in a ``sh`` block
  above the marker, the block shows that run's output; otherwise the command
  runs at the marker's place in the page (after the ``sh`` blocks above it),
  which is how a page shows a variant or an error message (exit status 2) it
  does not ask the reader to type.
- The blocks of a page run in order in one fresh copy of the repository, as
  ``tests/test_docs_commands.py`` runs them (its helpers, not a copy).
- A block may be an excerpt: its lines appear in the output in the same
  order, consecutive, a line ``...`` standing for any lines left out; a block
  that does not start (end) with ``...`` starts (ends) where the output does.
  Lines are compared without trailing blanks.
- Figures are compared as text, exactly, for commands that are deterministic
  (seeded simulations, fixed plans). Where a figure may move in its last
  digits with the BLAS or the platform, the marker says how far:
  ``<!-- output (numbers to 2 in the last digit) of: COMMAND -->`` compares
  the text between numbers and the whole numbers (counts of points, of
  alignments) exactly, and each other number to within 2 units of its last
  shown digit (``0.426`` matches 0.424 … 0.428, ``-67.6`` matches -67.8 …
  -67.4).

Use from the top folder of a clone::

    .venv/bin/python tests/docs_output.py --check            # differences, exit status 1 if any
    .venv/bin/python tests/docs_output.py --write docs/plan.md   # rewrite the blocks that differ

``--write`` keeps a block that matches; replaces a whole block by the output;
in an excerpt, replaces each shown line by the output line of the same words
(the numbers aside), and leaves the block for a person to edit when a shown
line's words are gone from the output.
"""
from __future__ import annotations

import argparse
import difflib
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_docs_commands import _commands, _fresh_clone, _pages, _run  # noqa: E402

MARKER = re.compile(
    r"^<!--[ \t]*output(?:[ \t]*\(numbers to (?P<digits>\d+) in the last digit\))?"
    r"[ \t]+of:[ \t]*(?P<command>.+?)[ \t]*-->"
    r"[ \t]*\n(?:[ \t]*\n)*```text[ \t]*\n(?P<body>.*?)^```", re.S | re.M)
ANY_MARKER = re.compile(r"^<!--[ \t]*output\b.*?-->", re.M)
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
GAP = "..."


@dataclass(frozen=True)
class Marked:
    """One marked block of a page: its command, the tolerance of its numbers and the lines it shows."""

    command: str
    digits: int | None  # numbers to within this many units of their last shown digit; None: exact text
    shown: tuple
    body_start: int  # the block's body in the page's text
    body_end: int
    line: int  # the marker's line in the page, from 1


def marked_blocks(text: str) -> list:
    """The page's marked ``text`` blocks, in page order."""
    out = []
    for m in MARKER.finditer(text):
        command = m.group("command")
        if command.startswith("kinid "):
            command = ".venv/bin/" + command
        digits = m.group("digits")
        out.append(Marked(command, int(digits) if digits else None, tuple(m.group("body").splitlines()),
                          m.start("body"), m.end("body"), text.count("\n", 0, m.start()) + 1))
    return out


def malformed_markers(text: str) -> list:
    """Line numbers of ``<!-- output ... -->`` comments that bind no ``text`` block (a typo would check nothing)."""
    bound = {m.start() for m in MARKER.finditer(text)}
    return [text.count("\n", 0, m.start()) + 1 for m in ANY_MARKER.finditer(text) if m.start() not in bound]


def run_page(page: Path, clone: Path) -> list:
    """Run the page's commands in order in ``clone``; (Marked, printed output, exit status) per marked block."""
    text = page.read_text(encoding="utf-8")
    outputs, results, done = {}, [], 0
    for mark in marked_blocks(text):
        for command in _commands(text[done:mark.body_start]):
            out = _run(command, clone, stderr=subprocess.STDOUT)
            if out.returncode != 0:
                raise RuntimeError(f"{page.name}: `{command}` exited {out.returncode}:\n{out.stdout[-2000:]}")
            outputs[command] = (out.stdout, out.returncode)
        done = mark.body_end
        if mark.command not in outputs:
            out = _run(mark.command, clone, stderr=subprocess.STDOUT)
            outputs[mark.command] = (out.stdout, out.returncode)
        results.append((mark,) + outputs[mark.command])
    return results


def _same_line(shown: str, printed: str, digits: int | None) -> bool:
    shown, printed = shown.rstrip(), printed.rstrip()
    if digits is None:
        return shown == printed
    if NUMBER.split(shown) != NUMBER.split(printed):
        return False
    for a, b in zip(NUMBER.findall(shown), NUMBER.findall(printed)):
        if re.fullmatch(r"[-+]?\d+", a):  # a count (points, alignments): exactly
            if a != b:
                return False
            continue
        mantissa, _, exponent = a.lower().partition("e")
        decimals = len(mantissa.partition(".")[2]) - int(exponent or 0)
        if abs(float(a) - float(b)) > digits * 10.0 ** -decimals * (1 + 1e-9):
            return False
    return True


def _chunks(shown) -> list:
    chunks, current = [], []
    for line in shown:
        if line.strip() == GAP:
            chunks.append(current)
            current = []
        else:
            current.append(line)
    return chunks + [current]


def matches(shown, printed, digits: int | None = None) -> bool:
    """Whether the shown lines are the printed ones, or an excerpt of them (``...`` for lines left out)."""
    shown, printed = list(shown), list(printed)
    while printed and not printed[-1].strip():
        printed.pop()
    chunks = _chunks(shown)
    if len(chunks) == 1:
        return len(chunks[0]) == len(printed) and all(map(_same_line, chunks[0], printed, [digits] * len(printed)))

    def at(chunk, i):
        return i + len(chunk) <= len(printed) and all(_same_line(s, p, digits) for s, p in zip(chunk, printed[i:]))

    first, middle, last = chunks[0], chunks[1:-1], chunks[-1]
    if not at(first, 0):
        return False
    cursor = len(first)
    for chunk in middle:
        found = next((i for i in range(cursor, len(printed) - len(chunk) + 1) if at(chunk, i)), None)
        if found is None:
            return False
        cursor = found + len(chunk)
    return len(printed) - len(last) >= cursor and at(last, len(printed) - len(last))


def _words(line: str) -> str:
    return NUMBER.sub("#", line.rstrip())


def rewritten(shown, printed, digits: int | None = None):
    """The block as it should read: unchanged if it matches; else the output, or the excerpt's lines updated.

    None when an excerpt cannot be updated (a shown line's words are not in the output, in order)."""
    shown, printed = list(shown), [line.rstrip() for line in printed]
    while printed and not printed[-1]:
        printed.pop()
    if matches(shown, printed, digits):
        return shown
    if not any(line.strip() == GAP for line in shown):
        return printed
    new, cursor = [], 0
    for line in shown:
        if line.strip() == GAP:
            new.append(line)
            continue
        found = next((i for i in range(cursor, len(printed)) if _words(printed[i]) == _words(line)), None)
        if found is None:
            return None
        new.append(printed[found])
        cursor = found + 1
    return new if matches(new, printed, digits) else None


def differences(page: Path, results) -> list:
    """One report per marked block that differs from its command's output (a unified diff)."""
    out = []
    for mark, printed, status in results:
        if matches(mark.shown, printed.splitlines(), mark.digits):
            continue
        new = rewritten(mark.shown, printed.splitlines(), mark.digits) or printed.splitlines()
        diff = "\n".join(difflib.unified_diff(list(mark.shown), new, "shown", "printed", lineterm="", n=1))
        out.append(f"{page.name}:{mark.line}: the block differs from what `{mark.command}` prints "
                   f"(exit status {status}):\n{diff}")
    return out


def write_page(page: Path, results) -> list:
    """Rewrite the page's blocks that differ, whole or not at all; the blocks that need a person's edit."""
    from kinid.files import write_text

    text = page.read_text(encoding="utf-8")
    stuck, pieces, done = [], [], 0
    for mark, printed, status in results:
        new = rewritten(mark.shown, printed.splitlines(), mark.digits)
        if new is None or status not in (0, 2):
            stuck.append(f"{page.name}:{mark.line}: `{mark.command}` (exit status {status}): "
                         "an excerpt line's words are not in the output, or the command failed: edit it by hand")
            new = list(mark.shown)
        pieces += [text[done:mark.body_start], "".join(line + "\n" for line in new)]
        done = mark.body_end
    new_text = "".join(pieces) + text[done:]
    if new_text != text:
        write_text(page, new_text)
    return stuck


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="print the differences; exit status 1 if any")
    mode.add_argument("--write", action="store_true", help="rewrite the blocks that differ in place")
    parser.add_argument("pages", nargs="*", type=Path, help="pages (default: README.md and docs/*.md)")
    args = parser.parse_args(argv)
    pages = [p.resolve() for p in args.pages] or _pages()
    problems = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        problems += [f"{page.name}:{line}: an output marker not right before a ```text block"
                     for line in malformed_markers(text)]
        if not marked_blocks(text):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            results = run_page(page, _fresh_clone(Path(tmp)))
        problems += write_page(page, results) if args.write else differences(page, results)
        print(f"{page.name}: {len(results)} marked blocks", file=sys.stderr)
    for problem in problems:
        print(problem)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
