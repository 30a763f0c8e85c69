"""The robot's screens (the tablet on its mast): device tokens that open the screen page and nothing else.

A screen is not a person: it has no password and no role. ``atemr screen add NAME`` makes a random token,
prints it once and stores only its SHA-256 (the token is 256 random bits, so a fast hash is enough, as for
the login sessions in `atemr.ui.users`), in the same SQLite file as the users (table ``screens``). The
token is looked up on every request and Socket.IO event of the screen, so ``atemr screen revoke NAME``
takes effect at once.
"""

from __future__ import annotations

import hashlib
import re
import secrets
import sqlite3
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path

from atemr.errors import AtemrError

SCREEN_NAME_RE = re.compile(r"^[A-Za-z0-9_.-]{1,32}$")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS screens (
    name TEXT PRIMARY KEY,
    token_hash TEXT NOT NULL UNIQUE,
    created REAL NOT NULL
);
"""


class ScreenError(AtemrError):
    """A screen operation was refused: a bad or taken name, or no such screen."""


@dataclass(frozen=True)
class Screen:
    """A screen as the console lists it (never its token)."""

    name: str
    created_unix_s: float


def token_hash(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8", "surrogatepass")).hexdigest()


def check_screen_name(name: str) -> str:
    if not isinstance(name, str) or not SCREEN_NAME_RE.match(name):
        raise ScreenError("a screen name is 1 to 32 letters, digits, '_', '.' or '-'")
    return name


class ScreenStore:
    """Screen tokens in the users SQLite file at ``path`` (created 0600 by `atemr.ui.users.UserStore`)."""

    def __init__(self, path: Path | str, *, now: Callable[[], float] = time.time) -> None:
        from atemr.ui.users import _private_file

        self.path = Path(path)
        self._now = now
        self.path.parent.mkdir(parents=True, exist_ok=True)
        _private_file(self.path)
        with self._db() as db:
            db.executescript(_SCHEMA)

    @contextmanager
    def _db(self) -> Iterator[sqlite3.Connection]:
        with closing(sqlite3.connect(self.path, timeout=10.0)) as conn, conn:
            yield conn

    def add(self, name: str) -> str:
        """A new screen called ``name``: its token, to be shown once (only its hash is kept)."""
        check_screen_name(name)
        token = secrets.token_urlsafe(32)
        try:
            with self._db() as db:
                db.execute("INSERT INTO screens (name, token_hash, created) VALUES (?, ?, ?)",
                           (name, token_hash(token), self._now()))
        except sqlite3.IntegrityError:
            raise ScreenError(f"a screen called {name!r} exists; revoke it first to make a new token") from None
        return token

    def list(self) -> list[Screen]:
        with self._db() as db:
            rows = db.execute("SELECT name, created FROM screens ORDER BY name COLLATE NOCASE").fetchall()
        return [Screen(r[0], float(r[1])) for r in rows]

    def revoke(self, name: str) -> None:
        """Delete the screen ``name``: its token opens nothing from now on."""
        with self._db() as db:
            cur = db.execute("DELETE FROM screens WHERE name = ?", (name,))
        if cur.rowcount == 0:
            raise ScreenError(f"no screen called {name!r}")

    def verify(self, token: str) -> str | None:
        """The name of the screen whose token is ``token``, or None."""
        if not isinstance(token, str) or not token or len(token) > 200:
            return None
        with self._db() as db:
            row = db.execute("SELECT name FROM screens WHERE token_hash = ?", (token_hash(token),)).fetchone()
        return str(row[0]) if row else None

    def live(self, tokens: Collection[str]) -> set[str]:
        """Those of ``tokens`` that still belong to a screen (the others were revoked)."""
        by_hash = {token_hash(t): t for t in tokens}
        if not by_hash:
            return set()
        keys = list(by_hash)
        with self._db() as db:
            rows = db.execute(f"SELECT token_hash FROM screens WHERE token_hash IN ({','.join('?' * len(keys))})",
                              keys).fetchall()
        return {by_hash[r[0]] for r in rows}
