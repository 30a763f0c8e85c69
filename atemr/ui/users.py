"""The dashboard's users, in SQLite: scrypt password hashes and the roles none/user/admin.

There is no default password. The root ``admin`` row is created without one on the first start, and
nobody can log in as ``admin`` until its password is set (from the console with
``atemr user set-password admin`` or from the first-start page served to localhost only). The root
admin can be neither removed nor demoted. New users get the role ``none``: they exist but see only the
no-access page until an admin grants them access.

Sessions live here too (table ``sessions``): a login stores the SHA-256 of a random token that the signed
session cookie carries, and every request and Socket.IO event looks the token up (one primary-key read
joined with the user's row). Logging out deletes the token; a password change, a role change and a removal
delete every token of that user, and a re-created user starts with none, so an old cookie never works again.

Password hashing (scrypt, ~32 MB and ~85 ms each) runs at most `HASH_SLOTS` at a time; a call that cannot
get a slot within `HASH_WAIT_S` raises `PasswordHashBusy` instead of queueing.

Each call opens its own short-lived connection, so the store is safe to share between the web
server's request threads; SQLite serialises the writes. The file is created 0600 (it holds the hashes).
"""

from __future__ import annotations

import hashlib
import os
import re
import secrets
import sqlite3
import threading
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from werkzeug.security import check_password_hash, generate_password_hash

from atemr.errors import AtemrError
from atemr.ui.permissions import ROLES, Permission, Role, role_at_least, role_may

ROOT_USER = "admin"
MIN_PASSWORD_LENGTH = 8
MAX_PASSWORD_LENGTH = 256
USERNAME_RE = re.compile(r"^[A-Za-z0-9_.-]{1,32}$")
HASH_METHOD = "scrypt"
#: Password hashes computed at once (each scrypt hash holds ~32 MB for ~85 ms).
HASH_SLOTS = 2
#: How long a hash waits for a free slot before `PasswordHashBusy`.
HASH_WAIT_S = 1.0
#: A session's lifetime without use (the cookie's too); each use pushes it on.
SESSION_LIFETIME_S = 12 * 3600.0
#: Sessions kept per user (the oldest go first).
MAX_SESSIONS_PER_USER = 32

_SCHEMA = """
CREATE TABLE IF NOT EXISTS users (
    username TEXT PRIMARY KEY,
    password_hash TEXT,
    role TEXT NOT NULL CHECK (role IN ('none', 'user', 'admin'))
);
CREATE TABLE IF NOT EXISTS sessions (
    token_hash TEXT PRIMARY KEY,
    username TEXT NOT NULL,
    created REAL NOT NULL,
    expires REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS sessions_by_user ON sessions (username);
"""


class UserError(AtemrError):
    """A user operation was refused: bad name or password, unknown user, or a rule about the root admin."""


class PasswordHashBusy(AtemrError):  # noqa: N818 (a state, not a mistake: "busy, try again")
    """Every password-hashing slot stayed taken for `HASH_WAIT_S`: the caller answers "busy, retry"."""


def _token_hash(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8", "surrogatepass")).hexdigest()


def _private_file(path: Path) -> None:
    """Create ``path`` 0600 if it is missing; tighten it (and SQLite's side files) to 0600 if it exists."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        pass
    else:
        os.close(fd)
    for file in (path, *(path.with_name(path.name + side) for side in ("-wal", "-shm", "-journal"))):
        try:
            if file.stat().st_mode & 0o077:
                os.chmod(file, 0o600)
        except FileNotFoundError:
            continue
        except PermissionError:  # not ours (a shared, read-only install): leave it as it is
            continue


@dataclass(frozen=True)
class User:
    """A dashboard user as the web app sees it (never the hash)."""

    username: str
    role: Role
    has_password: bool

    @property
    def is_root(self) -> bool:
        return self.username == ROOT_USER

    def can(self, role: Role) -> bool:
        """True when this user's role is at least ``role`` (none < user < admin)."""
        return role_at_least(self.role, role)

    def may(self, permission: Permission, user_permissions: Collection[Permission]) -> bool:
        """Whether this user may do a destructive or safety action (see `atemr.ui.permissions`)."""
        return role_may(self.role, permission, user_permissions)


def check_username(username: str) -> str:
    """``username`` if it is 1-32 letters, digits, ``_``, ``.`` or ``-``; else `UserError`."""
    if not isinstance(username, str) or not USERNAME_RE.match(username):
        raise UserError("a username is 1 to 32 letters, digits, '_', '.' or '-'")
    return username


def check_password(password: str) -> str:
    """``password`` if it is long enough (8) and not absurdly long (256); else `UserError`."""
    if not isinstance(password, str) or len(password) < MIN_PASSWORD_LENGTH:
        raise UserError(f"a password has at least {MIN_PASSWORD_LENGTH} characters")
    if len(password) > MAX_PASSWORD_LENGTH:
        raise UserError(f"a password has at most {MAX_PASSWORD_LENGTH} characters")
    return password


class UserStore:
    """Users in the SQLite file at ``path``; the schema and the password-less root admin are created on
    first use."""

    def __init__(
        self,
        path: Path | str,
        *,
        hash_method: str = HASH_METHOD,
        session_lifetime_s: float = SESSION_LIFETIME_S,
        hash_slots: int = HASH_SLOTS,
        hash_wait_s: float = HASH_WAIT_S,
        now: Callable[[], float] = time.time,
    ) -> None:
        if not hash_method.startswith("scrypt"):
            raise UserError(f"passwords are hashed with scrypt, not {hash_method!r}")
        self.path = Path(path)
        self.hash_method = hash_method  # "scrypt" or "scrypt:n:r:p" (cheaper parameters make tests fast)
        self.session_lifetime_s = float(session_lifetime_s)
        self.hash_wait_s = float(hash_wait_s)
        self._hash_slots = threading.BoundedSemaphore(hash_slots)
        self._now = now  # wall clock: session expiry outlives a restart
        self._dummy_hash = generate_password_hash("not-a-real-password", hash_method)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        _private_file(self.path)
        with self._db() as db:
            db.executescript(_SCHEMA)
            db.execute(
                "INSERT OR IGNORE INTO users (username, password_hash, role) VALUES (?, NULL, 'admin')", (ROOT_USER,)
            )
            # An old or hand-edited file must not leave the root admin demoted.
            db.execute("UPDATE users SET role = 'admin' WHERE username = ?", (ROOT_USER,))

    @contextmanager
    def _db(self) -> Iterator[sqlite3.Connection]:
        with closing(sqlite3.connect(self.path, timeout=10.0)) as conn, conn:
            yield conn

    @contextmanager
    def _hashing(self) -> Iterator[None]:
        """One of `HASH_SLOTS` password-hashing slots, or `PasswordHashBusy` after ``hash_wait_s``."""
        if not self._hash_slots.acquire(timeout=self.hash_wait_s):
            raise PasswordHashBusy("the dashboard is busy checking passwords: try again in a moment")
        try:
            yield
        finally:
            self._hash_slots.release()

    def _hash(self, password: str) -> str:
        with self._hashing():
            return generate_password_hash(password, self.hash_method)

    def _check(self, password_hash: str, password: str) -> bool:
        with self._hashing():
            return check_password_hash(password_hash, password)

    # -- reading -----------------------------------------------------------------------------------
    def get(self, username: str) -> User | None:
        """The user called ``username``, or None."""
        with self._db() as db:
            row = db.execute(
                "SELECT username, role, password_hash IS NOT NULL FROM users WHERE username = ?", (username,)
            ).fetchone()
        return User(row[0], cast(Role, row[1]), bool(row[2])) if row else None

    def list(self) -> list[User]:
        """Every user, the root admin first, then by name."""
        with self._db() as db:
            rows = db.execute(
                "SELECT username, role, password_hash IS NOT NULL FROM users "
                "ORDER BY username != ?, username COLLATE NOCASE",
                (ROOT_USER,),
            ).fetchall()
        return [User(r[0], cast(Role, r[1]), bool(r[2])) for r in rows]

    def needs_root_password(self) -> bool:
        """True until the root admin's password has been set (the first start)."""
        root = self.get(ROOT_USER)
        return root is None or not root.has_password

    def verify(self, username: str, password: str) -> User | None:
        """The user if ``password`` is theirs, else None (unknown users cost a hash too, so timing does
        not tell which names exist)."""
        with self._db() as db:
            row = db.execute(
                "SELECT username, role, password_hash FROM users WHERE username = ?", (username,)
            ).fetchone()
        if row is None or row[2] is None:
            self._check(self._dummy_hash, password)
            return None
        if not self._check(row[2], password):
            return None
        return User(row[0], cast(Role, row[1]), True)

    # -- writing -----------------------------------------------------------------------------------
    def create(self, username: str, password: str, role: Role = "none") -> User:
        """Add a user (role ``none`` unless told otherwise); `UserError` if the name is taken."""
        check_username(username)
        check_password(password)
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}: one of {', '.join(ROLES)}")
        password_hash = self._hash(password)
        try:
            with self._db() as db:
                db.execute(
                    "INSERT INTO users (username, password_hash, role) VALUES (?, ?, ?)",
                    (username, password_hash, role),
                )
                db.execute("DELETE FROM sessions WHERE username = ?", (username,))  # a new account starts fresh
        except sqlite3.IntegrityError:
            raise UserError(f"the username {username!r} is taken") from None
        return User(username, role, True)

    def set_password(self, username: str, password: str) -> None:
        """Replace ``username``'s password (also how the root admin's first password is set); every
        session of that user ends."""
        check_password(password)
        password_hash = self._hash(password)
        with self._db() as db:
            cur = db.execute("UPDATE users SET password_hash = ? WHERE username = ?", (password_hash, username))
            db.execute("DELETE FROM sessions WHERE username = ?", (username,))
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")

    def set_role(self, username: str, role: Role) -> None:
        """Grant or revoke access (``user``/``none``) or admin rights; the root admin stays admin. Every
        session of that user ends (they log in again with the new role)."""
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}: one of {', '.join(ROLES)}")
        if username == ROOT_USER and role != "admin":
            raise UserError("the root admin cannot be demoted")
        with self._db() as db:
            cur = db.execute("UPDATE users SET role = ? WHERE username = ?", (role, username))
            db.execute("DELETE FROM sessions WHERE username = ?", (username,))
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")

    def remove(self, username: str) -> None:
        """Delete a user and their sessions; the root admin cannot be removed."""
        if username == ROOT_USER:
            raise UserError("the root admin cannot be removed")
        with self._db() as db:
            cur = db.execute("DELETE FROM users WHERE username = ?", (username,))
            db.execute("DELETE FROM sessions WHERE username = ?", (username,))
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")

    # -- sessions ----------------------------------------------------------------------------------------
    def open_session(self, username: str) -> str:
        """A new session of ``username``: the token its cookie carries (only its hash is stored)."""
        token = secrets.token_urlsafe(32)
        now = self._now()
        with self._db() as db:
            db.execute("DELETE FROM sessions WHERE expires <= ?", (now,))
            db.execute("INSERT INTO sessions (token_hash, username, created, expires) VALUES (?, ?, ?, ?)",
                       (_token_hash(token), username, now, now + self.session_lifetime_s))
            db.execute(
                "DELETE FROM sessions WHERE username = ? AND token_hash NOT IN "
                "(SELECT token_hash FROM sessions WHERE username = ? ORDER BY created DESC LIMIT ?)",
                (username, username, MAX_SESSIONS_PER_USER),
            )
        return token

    def session_user(self, token: str) -> User | None:
        """The user of the live session ``token``, or None (logged out, expired, revoked, user gone).

        A session used after half its lifetime is extended (one write per half lifetime at most)."""
        now = self._now()
        key = _token_hash(token)
        with self._db() as db:
            row = db.execute(
                "SELECT u.username, u.role, u.password_hash IS NOT NULL, s.expires FROM sessions s "
                "JOIN users u ON u.username = s.username WHERE s.token_hash = ? AND s.expires > ?",
                (key, now),
            ).fetchone()
            if row is None:
                return None
            if row[3] - now < self.session_lifetime_s / 2:
                db.execute("UPDATE sessions SET expires = ? WHERE token_hash = ?", (now + self.session_lifetime_s, key))
        return User(row[0], cast(Role, row[1]), bool(row[2]))

    def live_sessions(self, tokens: Collection[str]) -> set[str]:
        """Those of ``tokens`` that are live sessions of users with access (role ``user`` or more)."""
        by_hash = {_token_hash(t): t for t in tokens}
        keys = list(by_hash)
        live: set[str] = set()
        now = self._now()
        with self._db() as db:
            for i in range(0, len(keys), 500):
                chunk = keys[i:i + 500]
                rows = db.execute(
                    f"SELECT s.token_hash FROM sessions s JOIN users u ON u.username = s.username "
                    f"WHERE s.expires > ? AND u.role != 'none' AND s.token_hash IN ({','.join('?' * len(chunk))})",
                    (now, *chunk),
                ).fetchall()
                live.update(by_hash[r[0]] for r in rows)
        return live

    def close_session(self, token: str) -> None:
        """End one session (logout)."""
        with self._db() as db:
            db.execute("DELETE FROM sessions WHERE token_hash = ?", (_token_hash(token),))

    def end_sessions(self, username: str) -> None:
        """End every session of ``username``."""
        with self._db() as db:
            db.execute("DELETE FROM sessions WHERE username = ?", (username,))


