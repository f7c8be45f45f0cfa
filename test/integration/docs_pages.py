"""Run a page of the docs as a user copies it: its commands, in a fresh copy of the repository.

``test_docs_pages.py`` has one test per tutorial and how-to page. Each reads the
page at test time (from the fresh copy, its ``--8<--`` snippets expanded from
the files of the copy), saves the files it shows, runs its commands and checks
what they print, so a page that no longer runs as written fails.

What a page holds, for this harness:

* A ```` ```bash ```` block: commands, one per line (a line ending with ``\\``
  goes on), each run by bash from the root of the copy, stdout and stderr
  together as a terminal shows them. A command must exit 0, unless its own
  comment says ``# exit N: ...`` (or ``# exit 0, 4 or 5: ...``).
  ``# terminal N: ...`` lines split a block into terminals: a bash block
  with terminals and the later ones with new terminal numbers form one
  session, whose terminals run at the same time, each its commands in turn,
  as a user with N terminals would. Terminals that name the page's domain
  (below) share it; each other one is a shell of its own, whose runs take a
  domain of their own (as a user's runs derive theirs from their pids).
* A ```` ```text ```` block right after a bash block (no other fenced block
  between): what that block printed (see :func:`output_mismatch` for the
  rules). After a session, ``output of terminal N`` says whose output it is.
* A fenced block with a title (```` ```yaml title="runs/study.yaml" ````,
  which the site shows above the block): a file the page asks the user to
  save; it is written there, in the copy, when the page reaches it.
* Every other block (```` ```python ````, ```` ```yaml ```` without a title,
  a block without a language) is shown, not run.

Markers: an HTML comment right before a block (blank lines between at most),
``<!-- docs-test: ... -->``, one directive per line; the reader of the page
source sees them, the reader of the site does not:

* ``skip PREFIX -- REASON``: the block's commands that start with ``PREFIX``
  are not run (``skip all -- REASON``: none of the block's). A command that is
  neither run nor skipped fails the test, and so does a ``skip`` that matches
  no command.
* ``not output -- REASON``: a text block that is not a command's output.
* ``output of terminal N``: the text block is terminal N's output.
* ``ctrl-c terminal N after terminal M`` / ``ctrl-c terminal N after "TEXT" ...``:
  the session sends SIGINT to terminal N's process group (what Ctrl-C does)
  once terminal M has ended, or once every TEXT is in terminal N's output.
* ``instead of terminal N: COMMAND -- REASON``: terminal N's commands are all
  skipped, and the session runs COMMAND in its place (a stand-in of what the
  suite cannot install, e.g. ros2_control).
* ``given NAME ARG -- REASON``: before the block, the test makes what the page
  presupposes (e.g. a run killed as a whole), by the test's function NAME.

What differs from a user's shell, and only this: the copy's ``.venv`` is a
venv of its own layered on the suite's (:func:`layered_venv`: what it
installs stays in it); the ROS domain is the test's (``--domain-id 42`` and
``ROS_DOMAIN_ID=42``, the pages' domain, become the test's domain, in the
commands and in their expected output), with the suite's isolation (localhost
discovery, UDP, a temporary ROS_LOG_DIR); pip works offline (no index, no
build isolation: the venv's setuptools builds). Afterwards nothing may be
left outside ``runs/`` but the tools' caches and a package's ``*.egg-info``,
each covered by ``.gitignore``, and no tracked file may have changed.
"""

from __future__ import annotations

import hashlib
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: The domain the pages write (``--domain-id 42``, ``ROS_DOMAIN_ID=42``).
PAGE_DOMAIN = 42
#: By-products that may be left outside ``runs/`` (each must be ignored by git).
TOOL_CACHES = ("__pycache__", ".ruff_cache", ".mypy_cache", ".pytest_cache")
_FENCE = re.compile(r"^```([\w+-]*)(.*)$")
_TITLE = re.compile(r'title="([^"]+)"')
_SNIPPET = re.compile(r'^\s*--8<--\s+"([^"]+)"\s*$')
_TERMINAL = re.compile(r"^#\s*terminal (\d+)\b")
_EXIT = re.compile(r"^#\s*exit ((?:\d+(?:, | or |, or ))*\d+)\b")
_DOMAIN = re.compile(rf"(--domain-id |ROS_DOMAIN_ID=){PAGE_DOMAIN}\b")
_RUN_TIME = re.compile(r"\d{8}-\d{6}")
_SENTINEL = "\x1edocs-test"


class PageError(AssertionError):
    """A page that cannot be run as written (a malformed block or marker, a failed command)."""


@dataclass(frozen=True)
class Directive:
    """One line of a ``<!-- docs-test: ... -->`` marker."""

    kind: str  # skip, not output, output of terminal, ctrl-c, instead, given
    args: tuple[str, ...]
    reason: str
    line: int


@dataclass(frozen=True)
class Command:
    """One command of a bash block, as bash gets it."""

    text: str
    line: int
    terminal: int | None
    exit_codes: tuple[int, ...]  # expected: `# exit N[, M or K]` in its comment, else 0

    @property
    def bare(self) -> str:
        """The command without its trailing comment."""
        return _split_comment(self.text)[0].strip()


@dataclass(frozen=True)
class Block:
    """A fenced block of the page, its snippets expanded."""

    lang: str
    title: str | None
    text: str
    line: int
    directives: tuple[Directive, ...]
    commands: tuple[Command, ...] = ()

    def skip_reason(self, command: Command) -> str | None:
        for d in self.directives:
            if d.kind == "skip" and (d.args[0] == "all" or command.bare.startswith(d.args[0])):
                return d.reason
        if any(d.kind == "instead" and int(d.args[0]) == command.terminal for d in self.directives):
            return next(d.reason for d in self.directives if d.kind == "instead")
        return None

    @property
    def terminals(self) -> tuple[int, ...]:
        return tuple(sorted({c.terminal for c in self.commands if c.terminal is not None}))


@dataclass(frozen=True)
class Page:
    path: Path
    blocks: tuple[Block, ...]

    @property
    def name(self) -> str:
        return f"{self.path.parent.name}/{self.path.name}"


def _split_comment(line: str) -> tuple[str, str]:
    """``(code, comment)`` of a shell line: the comment starts at a ``#`` outside quotes
    that begins a word."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = ""
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i], line[i:]
    return line, ""


def _commands(text: str, first_line: int) -> tuple[Command, ...]:
    out: list[Command] = []
    terminal: int | None = None
    lines = text.split("\n")
    i = 0
    while i < len(lines):
        start = i
        logical = lines[i]
        while logical.endswith("\\") and i + 1 < len(lines):
            i += 1
            logical += "\n" + lines[i]
        i += 1
        stripped = logical.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            found = _TERMINAL.match(stripped)
            if found:
                terminal = int(found.group(1))
            continue
        comment = _split_comment(logical.split("\n")[-1])[1]
        expected = _EXIT.match(comment)
        out.append(
            Command(
                text=logical.strip(),
                line=first_line + 1 + start,
                terminal=terminal,
                exit_codes=tuple(int(n) for n in re.findall(r"\d+", expected.group(1)))
                if expected
                else (0,),
            )
        )
    return tuple(out)


def _directive(text: str, line: int) -> Directive:
    body, _, reason = text.partition(" -- ")
    body, reason = body.strip(), reason.strip()
    words = body.split()
    if body.startswith("skip ") and reason:
        return Directive("skip", (body.removeprefix("skip ").strip(),), reason, line)
    if body == "not output" and reason:
        return Directive("not output", (), reason, line)
    found = re.fullmatch(r"output of terminal (\d+)", body)
    if found:
        return Directive("output of terminal", (found.group(1),), reason, line)
    found = re.fullmatch(r'ctrl-c terminal (\d+) after (?:terminal (\d+)|((?:"[^"]+"\s*)+))', body)
    if found:
        n, m, printed = found.groups()
        texts = re.findall(r'"([^"]+)"', printed or "")
        return Directive("ctrl-c", (n, m or "", *texts), reason, line)
    found = re.fullmatch(r"instead of terminal (\d+): (.+)", body)
    if found and reason:
        return Directive("instead", found.groups(), reason, line)
    if words and words[0] == "given" and len(words) == 3 and reason:
        return Directive("given", (words[1], words[2]), reason, line)
    raise PageError(f"line {line}: not a docs-test directive (or no reason given): {text!r}")


def parse_page(path: Path, root: Path) -> Page:
    """The fenced blocks of the page at ``path``, snippets read from ``root``."""
    lines = path.read_text().split("\n")
    blocks: list[Block] = []
    pending: list[Directive] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("<!--") and "docs-test" in line:
            start = i
            comment = line
            while "-->" not in lines[i]:
                i += 1
                comment += "\n" + lines[i]
            body = comment.split("<!--", 1)[1].rsplit("-->", 1)[0].strip()
            body = body.removeprefix("docs-test").lstrip(":").strip()
            for offset, text in enumerate(body.split("\n")):
                if text.strip():
                    pending.append(_directive(text.strip(), start + 1 + offset))
            i += 1
            continue
        fence = _FENCE.match(line)
        if fence:
            opening = i + 1
            lang, info = fence.group(1), fence.group(2)
            title = _TITLE.search(info)
            body: list[str] = []
            i += 1
            while not lines[i].startswith("```"):
                snippet = _SNIPPET.match(lines[i])
                if snippet:
                    body += (root / snippet.group(1)).read_text().rstrip("\n").split("\n")
                else:
                    body.append(lines[i])
                i += 1
            text = "\n".join(body)
            blocks.append(
                Block(
                    lang=lang,
                    title=title.group(1) if title else None,
                    text=text,
                    line=opening,
                    directives=tuple(pending),
                    commands=_commands(text, opening) if lang == "bash" else (),
                )
            )
            pending = []
            i += 1
            continue
        if pending and line.strip():
            raise PageError(
                f"{path.name}:{pending[0].line}: a docs-test marker must stand right before "
                "its block (blank lines between at most)"
            )
        i += 1
    if pending:
        raise PageError(f"{path.name}:{pending[0].line}: a docs-test marker before no block")
    return Page(path, tuple(blocks))


# -- the output rules -----------------------------------------------------------------


def visible_lines(output: str) -> list[str]:
    """The lines a terminal would show: a carriage return overwrites its line."""
    return [line.split("\r")[-1].rstrip() for line in output.split("\n")]


def _line_pattern(expected: str) -> re.Pattern[str]:
    pieces = [p for p in re.split(r"(\.\.\.|\s+|\d{8}-\d{6})", expected.strip()) if p]
    parts = []
    for k, piece in enumerate(pieces):
        if piece == "...":
            parts.append(".*?")
        elif piece.isspace():
            beside = pieces[k - 1 : k] + pieces[k + 1 : k + 2]
            parts.append(r"\s*" if "..." in beside else r"\s+")
        elif _RUN_TIME.fullmatch(piece):
            parts.append(r"\d{8}-\d{6}")
        else:
            parts.append(re.escape(piece))
    return re.compile(r"\s*" + "".join(parts))


def output_mismatch(expected: str, output: str) -> str | None:
    """None if ``output`` shows ``expected``, else what is missing.

    The rules: the expected block is an excerpt of the output. Its lines are
    matched in order, each to a whole line of the output; consecutive expected
    lines match consecutive output lines, except across a line that is only
    ``...``, which stands for any number of lines. Within a line, ``...``
    stands for any text (a path, a time, a count; the blanks beside it
    included), a run of blanks for any run of blanks, and a run directory's time (``20261125-232600``) for any such
    time. Everything else, every number included, is as printed.
    """
    got = visible_lines(output)
    chunks: list[list[str]] = [[]]
    for line in expected.strip("\n").split("\n"):
        if line.strip() == "...":
            chunks.append([])
        else:
            chunks[-1].append(line)
    position = 0
    for chunk in (c for c in chunks if c):
        patterns = [_line_pattern(e) for e in chunk]
        for start in range(position, len(got) - len(chunk) + 1):
            if all(p.fullmatch(got[start + k]) for k, p in enumerate(patterns)):
                position = start + len(chunk)
                break
        else:
            first = next(
                (k for k in range(position, len(got)) if patterns[0].fullmatch(got[k])), None
            )
            where = (
                f"its first line is line {first + 1}, the next ones differ"
                if first is not None
                else f"no line after line {position} matches {chunk[0]!r}"
            )
            return f"the output does not show\n{chr(10).join(chunk)}\n({where})"
    return None


def page_domain(text: str, domain: int) -> str:
    """``text`` with the pages' ROS domain replaced by ``domain``."""
    return _DOMAIN.sub(rf"\g<1>{domain}", text)


# -- the copy and its venv ---------------------------------------------------------------


def fresh_copy(dest: Path, repo: Path = REPO) -> dict[str, str]:
    """The tracked files of ``repo`` as they are in its work tree, copied to ``dest`` (mtimes
    and symlinks kept; nothing shared with the checkout); their sha256 by relative path."""
    listed = subprocess.run(
        ["git", "-C", str(repo), "ls-files", "-z"], capture_output=True, check=True
    ).stdout.decode()
    hashes: dict[str, str] = {}
    for name in filter(None, listed.split("\0")):
        src, dst = repo / name, dest / name
        if not src.is_symlink() and not src.exists():
            continue  # deleted in the work tree
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():
            os.symlink(os.readlink(src), dst)
            hashes[name] = "symlink:" + os.readlink(src)
        else:
            shutil.copy2(src, dst)
            hashes[name] = hashlib.sha256(dst.read_bytes()).hexdigest()
    return hashes


def layered_venv(venv: Path, shared: Path = REPO / ".venv") -> Path:
    """A venv at ``venv`` that sees every package of ``shared`` and installs into itself.

    Made with ``venv --without-pip``; its site-packages gets a ``.pth`` that adds
    ``shared``'s site-packages after its own (so an installed package of its own
    comes first, and pip leaves ``shared``'s packages alone: "outside environment");
    ``shared``'s console scripts are written again for its interpreter (its programs,
    such as ruff, are symlinks); the ROS
    wheels' libraries (``lib/``, ``site-packages/ros_*.libs``, found from
    ``sys.prefix`` by their bootstrapper) and ``share/`` are symlinks to ``shared``'s.
    ``scripts/setup.sh``'s stamp says it is installed, as the shared venv is.
    """
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    site, shared_site = (
        venv / "lib" / version / "site-packages",
        shared / "lib" / version / "site-packages",
    )
    (site / "_servo_axis_shared.pth").write_text(
        f"import site; site.addsitedir({str(shared_site)!r})\n"
    )
    for libs in shared_site.glob("ros_*.libs"):
        os.symlink(libs, site / libs.name)
    for entry in (shared / "lib").iterdir():
        if entry.name != version and not (venv / "lib" / entry.name).exists():
            os.symlink(entry, venv / "lib" / entry.name)
    if (shared / "share").is_dir():
        os.symlink(shared / "share", venv / "share")
    shebang = f"#!{shared}/bin/python".encode()
    for script in (shared / "bin").iterdir():
        target = venv / "bin" / script.name
        if target.exists() or not script.is_file() or script.is_symlink():
            continue
        head = script.read_bytes()
        if head.startswith(shebang):
            rest = head.partition(b"\n")[2]
            target.write_bytes(f"#!{venv}/bin/python\n".encode() + rest)
            target.chmod(0o755)
        elif head.startswith(b"\x7fELF"):  # a program of its own (ruff): the same one
            os.symlink(script, target)
    (venv / ".servo_axis-installed").touch()
    return venv


def page_environment(domain: int) -> dict[str, str]:
    """The environment of the page's commands: the test's ROS isolation (set by its
    fixture in ``os.environ``), pip offline, none of the suite's venv's own variables."""
    env = dict(os.environ)
    for name in ("_ROS_WHEELS_BOOTSTRAP_COMPLETE", "LD_LIBRARY_PATH", "VIRTUAL_ENV", "PYTHONPATH"):
        env.pop(name, None)
    env.update(
        ROS_DOMAIN_ID=str(domain),
        PIP_NO_INDEX="1",
        PIP_NO_BUILD_ISOLATION="0",
        PIP_DISABLE_PIP_VERSION_CHECK="1",
        PYTHONUNBUFFERED="1",
    )
    return env


def left_behind(copy: Path, tracked: Mapping[str, str]) -> list[str]:
    """What the page's commands left outside ``runs/`` (tool caches that git ignores
    aside) and the tracked files they changed."""
    found = []
    for dirpath, dirnames, filenames in os.walk(copy):
        here = Path(dirpath).relative_to(copy)
        if here == Path("."):
            dirnames[:] = [d for d in dirnames if d not in (".venv", "runs")]
        caches = [d for d in dirnames if d in TOOL_CACHES or d.endswith(".egg-info")]
        for d in caches:
            if not _ignored(here / d):
                found.append(f"{here / d}/ (not ignored by .gitignore)")
        dirnames[:] = [d for d in dirnames if d not in caches]
        for name in [*filenames, *(d for d in dirnames if (Path(dirpath) / d).is_symlink())]:
            rel = str(here / name) if here != Path(".") else name
            if rel not in tracked:
                found.append(f"{rel} (untracked)")
    for rel, digest in tracked.items():
        path = copy / rel
        now = (
            "symlink:" + os.readlink(path)
            if path.is_symlink()
            else hashlib.sha256(path.read_bytes()).hexdigest()
            if path.is_file()
            else "gone"
        )
        if now != digest:
            found.append(f"{rel} (tracked, {'removed' if now == 'gone' else 'changed'})")
    return sorted(found)


def _ignored(rel: Path) -> bool:
    done = subprocess.run(
        ["git", "-C", str(REPO), "check-ignore", "-q", "--no-index", f"{rel}/"],
        capture_output=True,
    )
    return done.returncode == 0


# -- running a page ---------------------------------------------------------------------------


@dataclass
class Ran:
    """A command the page test ran: what it printed, its exit code (None: killed), its time
    (wall) and the CPU time of its processes (None: it ran beside others, in a session)."""

    command: Command
    output: str
    exit_code: int | None
    seconds: float
    cpu_s: float | None = None


def children_cpu_s() -> float:
    """User and system CPU time of this process's children that have ended (reaped), s."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return used.ru_utime + used.ru_stime


@dataclass
class PageResult:
    page: Page
    ran: list[Ran] = field(default_factory=list)
    skipped: list[tuple[Command, str]] = field(default_factory=list)
    seconds: float = 0.0
    cpu_s: float = 0.0  # of every process the page's commands, givens and looks started

    def output_of(self, prefix: str) -> str:
        """The output of the one command that starts with ``prefix``."""
        (found,) = [r for r in self.ran if r.command.bare.startswith(prefix)]
        return found.output

    def report(self) -> str:
        lines = [f"{self.page.name}: {self.seconds:.1f} s, {self.cpu_s:.1f} s of CPU"]
        lines += [
            f"  {r.seconds:6.1f} s  {'' if r.cpu_s is None else f'{r.cpu_s:5.1f} CPU s':>9}"
            f"  exit {r.exit_code}  {r.command.bare.splitlines()[0][:90]}"
            for r in self.ran
        ]
        reasons: dict[str, list[str]] = {}
        for command, why in self.skipped:
            reasons.setdefault(why, []).append(command.bare.splitlines()[0][:40])
        for why, commands in reasons.items():
            lines.append(f"  skipped {len(commands)}: {', '.join(commands)}  ({why})")
        return "\n".join(lines)


#: A page's preparation (``given NAME ARG``): ``(copy, arg, env)``.
Given = Callable[[Path, str, dict[str, str]], None]
#: What a test looks at right after one of the page's commands (by its prefix), before
#: the page goes on (e.g. before it uninstalls what it installed): ``(copy, env)``.
After = Callable[[Path, dict[str, str]], None]


class PageRun:
    """The commands of one page in ``copy``, in page order; see the module's docstring."""

    def __init__(
        self,
        page: Page,
        copy: Path,
        domain: int,
        *,
        givens: Mapping[str, Given] | None = None,
        after: Mapping[str, After] | None = None,
        more_domains: Callable[[], int] | None = None,
        timeout_s: float = 240.0,
    ) -> None:
        self.page, self.copy, self.domain = page, copy, domain
        self.env = page_environment(domain)
        self.more_domains = more_domains
        self.givens = dict(givens or {})
        self.after = dict(after or {})
        self._looked: set[str] = set()
        self.timeout_s = timeout_s
        self.result = PageResult(page)
        self.log_dir = copy.parent / "terminals"

    def run(self) -> PageResult:
        started, cpu = time.monotonic(), children_cpu_s()
        blocks = self.page.blocks
        outputs: dict[int, str] = {}  # block index -> what it printed
        terminals: dict[int, str] = {}  # of the last session
        i = 0
        while i < len(blocks):
            block = blocks[i]
            for d in block.directives:
                if d.kind == "given":
                    if d.args[0] not in self.givens:
                        raise PageError(f"{self.page.name}:{d.line}: no given {d.args[0]!r}")
                    self.givens[d.args[0]](self.copy, d.args[1], self.env)
            if block.lang == "bash" and block.terminals:
                # The session: this block and the later bash blocks of new terminals, up
                # to a bash block without terminals; the blocks between are shown, saved
                # (before the terminals start) or checked (once they have ended).
                session, seen, j = [i], set(block.terminals), i + 1
                while j < len(blocks) and not (
                    blocks[j].lang == "bash" and not blocks[j].terminals
                ):
                    if blocks[j].lang == "bash":
                        if set(blocks[j].terminals) & seen:
                            break
                        seen |= set(blocks[j].terminals)
                        session.append(j)
                    j += 1
                last = session[-1]
                between = [k for k in range(i + 1, last + 1) if k not in session]
                for k in between:
                    if blocks[k].title:
                        self._save(blocks[k])
                terminals = self._session([blocks[s] for s in session])
                for s in session:
                    outputs[s] = "".join(terminals.get(t, "") for t in blocks[s].terminals)
                for k in between:
                    if blocks[k].lang == "text":
                        self._check_text(blocks[k], k, outputs, terminals)
                i = last + 1
                continue
            if block.lang == "bash":
                outputs[i] = self._commands(block)
            elif block.lang == "text":
                self._check_text(block, i, outputs, terminals)
            elif block.title:
                self._save(block)
            i += 1
        self._check_markers()
        self.result.seconds = time.monotonic() - started
        self.result.cpu_s = children_cpu_s() - cpu
        return self.result

    # -- the blocks

    def _save(self, block: Block) -> None:
        """Write a titled block where its title says, in the clone."""
        assert block.title is not None
        target = (self.copy / block.title).resolve()
        if self.copy.resolve() not in target.parents:
            raise PageError(f"{self.page.name}:{block.line}: {block.title} is not in the clone")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(block.text + "\n")

    def _check_text(
        self, block: Block, index: int, outputs: dict[int, str], terminals: dict[int, str]
    ) -> None:
        if any(d.kind == "not output" for d in block.directives):
            return
        of = [d for d in block.directives if d.kind == "output of terminal"]
        if of:
            output = terminals.get(int(of[0].args[0]))
            if output is None:
                raise PageError(f"{self.page.name}:{block.line}: no terminal {of[0].args[0]} ran")
        elif index - 1 in outputs:
            output = outputs[index - 1]
        else:
            raise PageError(
                f"{self.page.name}:{block.line}: a text block after no bash block: mark it "
                "'not output -- REASON' or 'output of terminal N'"
            )
        problem = output_mismatch(page_domain(block.text, self.domain), output)
        if problem:
            raise PageError(
                f"{self.page.name}:{block.line}: {problem}\n--- output:\n{output[-4000:]}"
            )

    def _commands(self, block: Block) -> str:
        printed = []
        for command in block.commands:
            why = block.skip_reason(command)
            if why is not None:
                self.result.skipped.append((command, why))
                continue
            log = self._log(command)
            started, cpu = time.monotonic(), children_cpu_s()
            with log.open("wb") as out:
                proc = subprocess.Popen(
                    ["bash", "-c", page_domain(command.text, self.domain)],
                    cwd=self.copy,
                    env=self.env,
                    stdin=subprocess.DEVNULL,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
                try:
                    code: int | None = proc.wait(timeout=self.timeout_s)
                except subprocess.TimeoutExpired:
                    _stop(proc)
                    code = None
            output = log.read_text(errors="replace")
            used = children_cpu_s() - cpu
            self._ran(Ran(command, output, code, time.monotonic() - started, used))
            printed.append(output)
            for prefix, look in self.after.items():
                if command.bare.startswith(prefix):
                    look(self.copy, self.env)
                    self._looked.add(prefix)
        return "".join(printed)

    def _session(self, blocks: list[Block]) -> dict[int, str]:
        """Every terminal of ``blocks`` at once; their outputs."""
        scripts: dict[int, list[Command]] = {}
        instead: dict[int, str] = {}
        ctrl_c: list[Directive] = []
        for block in blocks:
            for command in block.commands:
                why = block.skip_reason(command)
                if why is not None:
                    self.result.skipped.append((command, why))
                else:
                    assert command.terminal is not None, command
                    scripts.setdefault(command.terminal, []).append(command)
            for d in block.directives:
                if d.kind == "instead":
                    instead[int(d.args[0])] = d.args[1]
                elif d.kind == "ctrl-c":
                    ctrl_c.append(d)
        # A terminal that does not name the page's domain is a shell of its own, whose runs
        # derive a domain of their own: each such terminal gets a fresh one, but for the
        # first when no terminal takes the test's as the page's.
        terminals = sorted(set(scripts) | set(instead))
        own = [
            n
            for n in terminals
            if not any(
                _DOMAIN.search(c.text) for b in blocks for c in b.commands if c.terminal == n
            )
            and not _DOMAIN.search(instead.get(n, ""))
        ]
        envs = {n: self.env for n in terminals}
        for n in own[1:] if len(own) == len(terminals) else own:
            if self.more_domains is None:
                raise PageError(
                    f"{self.page.name}: terminals {own} name no domain: each needs one of its "
                    "own (more_domains)"
                )
            envs[n] = {**self.env, "ROS_DOMAIN_ID": str(self.more_domains())}
        procs: dict[int, tuple[subprocess.Popen[bytes], Path, float]] = {}
        for n in sorted(set(scripts) | set(instead)):
            lines = []
            for command in scripts.get(n, []):
                lines.append(page_domain(command.text, self.domain))
                lines.append(f'printf "\\n{_SENTINEL} %s %s\\n" "$?" "$EPOCHREALTIME"')
            if n in instead:
                lines.append(page_domain(instead[n], self.domain))
                lines.append(f'printf "\\n{_SENTINEL} %s %s\\n" "$?" "$EPOCHREALTIME"')
            log = self.log_dir / f"terminal{n}.{time.monotonic_ns()}.log"
            log.parent.mkdir(exist_ok=True)
            with log.open("wb") as out:
                proc = subprocess.Popen(
                    ["bash", "-c", "\n".join(lines)],
                    cwd=self.copy,
                    env=envs[n],
                    stdin=subprocess.DEVNULL,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            procs[n] = (proc, log, time.time())
        sent: set[int] = set()
        deadline = time.monotonic() + self.timeout_s
        try:
            while any(p.poll() is None for p, _, _ in procs.values()):
                if time.monotonic() > deadline:
                    raise PageError(
                        f"{self.page.name}: the terminals did not end:\n{_tails(procs)}"
                    )
                for d in ctrl_c:
                    n, after, printed = int(d.args[0]), d.args[1], d.args[2:]
                    if n in sent or n not in procs or procs[n][0].poll() is not None:
                        continue
                    ready = (
                        procs[int(after)][0].poll() is not None
                        if after
                        else all(t in procs[n][1].read_text(errors="replace") for t in printed)
                    )
                    if ready:
                        os.killpg(procs[n][0].pid, signal.SIGINT)
                        sent.add(n)
                time.sleep(0.05)
        finally:
            for proc, _, _ in procs.values():
                if proc.poll() is None:
                    _stop(proc)
        outputs = {}
        for n, (_, log, began) in procs.items():
            text = log.read_text(errors="replace")
            pieces = text.split(f"\n{_SENTINEL} ")
            shown = [pieces[0]]
            commands = scripts.get(n, [])
            if n in instead:
                commands = [*commands, Command(instead[n], 0, n, (0,))]
            for k, command in enumerate(commands):
                if k + 1 < len(pieces):
                    status, _, rest = pieces[k + 1].partition("\n")
                    code_text, _, at = status.partition(" ")
                    code: int | None = int(code_text)
                    ended = float(at.replace(",", "."))
                else:
                    code, ended, rest = None, time.time(), ""
                self._ran(Ran(command, shown[-1], code, ended - began), where=f"terminal {n}")
                began = ended
                shown.append(rest)
            outputs[n] = "".join(shown[:-1]) if len(shown) > 1 else shown[0]
        return outputs

    # -- bookkeeping

    def _ran(self, ran: Ran, where: str = "") -> None:
        self.result.ran.append(ran)
        if ran.exit_code not in ran.command.exit_codes:
            raise PageError(
                f"{self.page.name}:{ran.command.line}{' (' + where + ')' if where else ''}: "
                f"{ran.command.bare!r} exited {ran.exit_code}, the page expects "
                f"{' or '.join(map(str, ran.command.exit_codes))}:\n{ran.output[-4000:]}"
            )

    def _log(self, command: Command) -> Path:
        self.log_dir.mkdir(exist_ok=True)
        return self.log_dir / f"line{command.line}.{time.monotonic_ns()}.log"

    def _check_markers(self) -> None:
        if set(self.after) - self._looked:
            raise PageError(
                f"{self.page.name}: no command starts with {sorted(set(self.after) - self._looked)}"
            )
        ran = {id(r.command) for r in self.result.ran}
        skipped = {id(c) for c, _ in self.result.skipped}
        for block in self.page.blocks:
            for command in block.commands:
                if id(command) not in ran | skipped:
                    raise PageError(f"{self.page.name}:{command.line}: not run: {command.bare!r}")
            for d in block.directives:
                if d.kind == "skip" and not any(
                    d.args[0] == "all" or c.bare.startswith(d.args[0]) for c in block.commands
                ):
                    raise PageError(
                        f"{self.page.name}:{d.line}: 'skip {d.args[0]}' matches no command"
                    )


def _stop(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT to its process group, then SIGKILL after 10 s."""
    try:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    except ProcessLookupError:
        proc.wait()


def _tails(procs: Mapping[int, tuple[subprocess.Popen[bytes], Path, float]]) -> str:
    return "\n".join(
        f"terminal {n}:\n{log.read_text(errors='replace')[-2000:]}"
        for n, (_, log, _) in procs.items()
    )
