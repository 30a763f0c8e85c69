"""Who may do what on the dashboard: the roles, and the destructive or safety actions each one needs.

Roles are ordered (``none`` < ``user`` < ``admin``): ``none`` sees only the no-access page, ``user`` drives
the robot (joystick, goals, missions, maps, media), ``admin`` does everything and manages users. The
actions below can hurt someone or lose data, so by default only ``admin`` may do them; a robot's
configuration can grant some of them to ``user`` as well (``ui.user_permissions``), for a household where
the carer who drives the robot is also the one who looks after it. Nothing is ever granted to ``none``.

This module is imported by the configuration (to type ``ui.user_permissions``), so it depends on nothing
but the standard library.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Literal, get_args

Role = Literal["none", "user", "admin"]
ROLES: tuple[Role, ...] = ("none", "user", "admin")
#: How the pages name each role (the users table and the add-user form alike).
ROLE_LABELS: dict[Role, str] = {"none": "no access", "user": "user", "admin": "admin"}

Permission = Literal["power", "delete_all", "agent_reload", "speed_limits", "awareness", "wifi"]
PERMISSIONS: tuple[Permission, ...] = get_args(Permission)
#: What each permission allows, as the dashboard and docs/dashboard.md#users-roles-and-permissions say it.
PERMISSION_LABELS: dict[Permission, str] = {
    "power": "press the robot's power button (power off, power on, OPS/CONFIG)",
    "delete_all": "delete all maps, images, videos or traces at once",
    "agent_reload": "reload the agent document",
    "speed_limits": "change the speed limits",
    "awareness": "turn awareness on or off (the robot then moves away from people by itself)",
    "wifi": "change the robot's WiFi",
}


def role_at_least(role: Role, needed: Role) -> bool:
    """True when ``role`` ranks at least ``needed`` (none < user < admin)."""
    return ROLES.index(role) >= ROLES.index(needed)


def role_may(role: Role, permission: Permission, user_permissions: Collection[Permission]) -> bool:
    """Whether an account with ``role`` may do ``permission``: admin always, user when the robot's
    configuration grants it (``user_permissions``), no-access never."""
    if role == "admin":
        return True
    return role == "user" and permission in user_permissions


def needed_role(permission: Permission, user_permissions: Collection[Permission]) -> Role:
    """The lowest role that may do ``permission`` (for messages such as "needs the admin role")."""
    return "user" if permission in user_permissions else "admin"
