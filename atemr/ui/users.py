"""The dashboard's users, in SQLite: scrypt password hashes and the roles none/user/admin.

There is no default password. The root ``admin`` row is created without one on the first start, and
nobody can log in as ``admin`` until its password is set (from the console with
``atemr user set-password admin`` or from the first-start page served to localhost only). The root
admin can be neither removed nor demoted. New users get the role ``none``: they exist but see only the
no-access page until an admin grants them access.

Each call opens its own short-lived connection, so the store is safe to share between the web
server's request threads; SQLite serialises the writes.
"""

from __future__ import annotations

import re
import sqlite3
from collections.abc import Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, cast

from werkzeug.security import check_password_hash, generate_password_hash

from atemr.errors import AtemrError

Role = Literal["none", "user", "admin"]
ROLES: tuple[Role, ...] = ("none", "user", "admin")
ROOT_USER = "admin"
MIN_PASSWORD_LENGTH = 8
MAX_PASSWORD_LENGTH = 256
USERNAME_RE = re.compile(r"^[A-Za-z0-9_.-]{1,32}$")
HASH_METHOD = "scrypt"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS users (
    username TEXT PRIMARY KEY,
    password_hash TEXT,
    role TEXT NOT NULL CHECK (role IN ('none', 'user', 'admin'))
);
"""


class UserError(AtemrError):
    """A user operation was refused: bad name or password, unknown user, or a rule about the root admin."""


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
        return ROLES.index(self.role) >= ROLES.index(role)


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

    def __init__(self, path: Path | str, *, hash_method: str = HASH_METHOD) -> None:
        if not hash_method.startswith("scrypt"):
            raise UserError(f"passwords are hashed with scrypt, not {hash_method!r}")
        self.path = Path(path)
        self.hash_method = hash_method  # "scrypt" or "scrypt:n:r:p" (cheaper parameters make tests fast)
        self._dummy_hash = generate_password_hash("not-a-real-password", hash_method)
        self.path.parent.mkdir(parents=True, exist_ok=True)
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
            check_password_hash(self._dummy_hash, password)
            return None
        if not check_password_hash(row[2], password):
            return None
        return User(row[0], cast(Role, row[1]), True)

    # -- writing -----------------------------------------------------------------------------------
    def create(self, username: str, password: str, role: Role = "none") -> User:
        """Add a user (role ``none`` unless told otherwise); `UserError` if the name is taken."""
        check_username(username)
        check_password(password)
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}: one of {', '.join(ROLES)}")
        try:
            with self._db() as db:
                db.execute(
                    "INSERT INTO users (username, password_hash, role) VALUES (?, ?, ?)",
                    (username, generate_password_hash(password, self.hash_method), role),
                )
        except sqlite3.IntegrityError:
            raise UserError(f"the username {username!r} is taken") from None
        return User(username, role, True)

    def set_password(self, username: str, password: str) -> None:
        """Replace ``username``'s password (also how the root admin's first password is set)."""
        check_password(password)
        with self._db() as db:
            cur = db.execute(
                "UPDATE users SET password_hash = ? WHERE username = ?",
                (generate_password_hash(password, self.hash_method), username),
            )
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")

    def set_role(self, username: str, role: Role) -> None:
        """Grant or revoke access (``user``/``none``) or admin rights; the root admin stays admin."""
        if role not in ROLES:
            raise UserError(f"unknown role {role!r}: one of {', '.join(ROLES)}")
        if username == ROOT_USER and role != "admin":
            raise UserError("the root admin cannot be demoted")
        with self._db() as db:
            cur = db.execute("UPDATE users SET role = ? WHERE username = ?", (role, username))
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")

    def remove(self, username: str) -> None:
        """Delete a user; the root admin cannot be removed."""
        if username == ROOT_USER:
            raise UserError("the root admin cannot be removed")
        with self._db() as db:
            cur = db.execute("DELETE FROM users WHERE username = ?", (username,))
        if cur.rowcount == 0:
            raise UserError(f"no user called {username!r}")


