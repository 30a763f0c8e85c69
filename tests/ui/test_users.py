import sqlite3

import pytest

from atemr.ui.users import ROOT_USER, UserError, UserStore

FAST = "scrypt:1024:8:1"


@pytest.fixture
def store(tmp_path):
    return UserStore(tmp_path / "db" / "users.sqlite3", hash_method=FAST)


def test_first_start_has_root_admin_without_password(store):
    root = store.get(ROOT_USER)
    assert root is not None and root.role == "admin" and not root.has_password
    assert store.needs_root_password()
    assert store.verify(ROOT_USER, "") is None and store.verify(ROOT_USER, "anything-at-all") is None


def test_passwords_are_scrypt_hashes_never_plain(store, tmp_path):
    store.set_password(ROOT_USER, "correct horse")
    assert not store.needs_root_password()
    assert store.verify(ROOT_USER, "correct horse").username == ROOT_USER
    assert store.verify(ROOT_USER, "wrong horse!") is None
    with sqlite3.connect(store.path) as db:
        (stored,) = db.execute("SELECT password_hash FROM users WHERE username='admin'").fetchone()
    assert stored.startswith("scrypt:") and "correct horse" not in stored


def test_new_users_have_no_access_until_granted(store):
    user = store.create("carol", "password1")
    assert user.role == "none" and not user.can("user")
    store.set_role("carol", "user")
    assert store.get("carol").can("user") and not store.get("carol").can("admin")
    store.set_role("carol", "admin")
    assert store.get("carol").can("admin")


def test_root_admin_can_be_neither_removed_nor_demoted(store):
    with pytest.raises(UserError, match="cannot be removed"):
        store.remove(ROOT_USER)
    for role in ("none", "user"):
        with pytest.raises(UserError, match="cannot be demoted"):
            store.set_role(ROOT_USER, role)
    assert store.get(ROOT_USER).role == "admin"


def test_root_admin_is_restored_if_the_file_was_edited(tmp_path):
    path = tmp_path / "u.sqlite3"
    UserStore(path, hash_method=FAST)
    with sqlite3.connect(path) as db:
        db.execute("UPDATE users SET role='none' WHERE username='admin'")
    assert UserStore(path, hash_method=FAST).get(ROOT_USER).role == "admin"


@pytest.mark.parametrize("name", ["", "a b", "x" * 33, "semi;colon", "../up", "ünï"])
def test_bad_usernames_are_refused(store, name):
    with pytest.raises(UserError, match="username"):
        store.create(name, "password1")


@pytest.mark.parametrize("password", ["", "short", "x" * 257])
def test_bad_passwords_are_refused(store, password):
    with pytest.raises(UserError, match="password"):
        store.create("dave", password)


def test_duplicates_unknown_users_and_bad_roles(store):
    store.create("erin", "password1")
    with pytest.raises(UserError, match="taken"):
        store.create("erin", "password2")
    with pytest.raises(UserError, match="no user"):
        store.set_password("nobody", "password1")
    with pytest.raises(UserError, match="no user"):
        store.remove("nobody")
    with pytest.raises(UserError, match="unknown role"):
        store.set_role("erin", "superuser")
    store.remove("erin")
    assert store.get("erin") is None


def test_list_root_first_then_by_name(store):
    for name in ("zed", "Amy", "bo"):
        store.create(name, "password1")
    assert [u.username for u in store.list()] == ["admin", "Amy", "bo", "zed"]


def test_only_scrypt_is_accepted(tmp_path):
    with pytest.raises(UserError, match="scrypt"):
        UserStore(tmp_path / "u.sqlite3", hash_method="pbkdf2:sha256")
