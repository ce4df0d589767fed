"""Who may use the operator station when it is served beyond loopback: users, roles, login.

A users file (TOML, written by ``bench station user``) holds each user's role and a salted
scrypt hash of the password — never the password::

    [users.ann]
    role = "operator"        # operator | engineer
    password = "scrypt$16384$8$1$<salt hex>$<hash hex>"

The server asks for HTTP Basic credentials (the browser's own login box; the page's requests
and its event stream carry them from then on) on every route.  Roles:

* **operator**: the page, start a batch (the run records the login as its operator), answer
  prompts, abort, retest, history and reports;
* **engineer**: all of that and the station health check (``bench doctor`` opens every
  instrument: not something to run under a batch's feet).

Basic credentials are only base64 on the wire: beyond loopback serve over TLS
(``--tls-cert``/``--tls-key``) or behind a TLS proxy, on the plant network.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import json
import os
import secrets
from collections.abc import Awaitable, Callable, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.core.toml_file import read_toml

ROLES = ("operator", "engineer")
#: routes only an engineer may use
ENGINEER_PATHS = ("/api/doctor",)
REALM = "operator station"
_SCRYPT = (16384, 8, 1)  # n, r, p: ~16 MiB, tens of ms a check
MIN_PASSWORD_CHARS = 8
_NAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-")


def hash_password(password: str, *, salt: bytes | None = None) -> str:
    """``scrypt$n$r$p$salt$hash`` of ``password`` (a fresh 16-byte salt unless given)."""
    salt = secrets.token_bytes(16) if salt is None else salt
    n, r, p = _SCRYPT
    digest = hashlib.scrypt(password.encode(), salt=salt, n=n, r=r, p=p, dklen=32)
    return f"scrypt${n}${r}${p}${salt.hex()}${digest.hex()}"


def verify_password(password: str, stored: str) -> bool:
    """Whether ``password`` matches ``stored`` (:func:`hash_password`'s form); constant time."""
    try:
        kind, n, r, p, salt, digest = stored.split("$")
        if kind != "scrypt":
            return False
        got = hashlib.scrypt(password.encode(), salt=bytes.fromhex(salt), n=int(n), r=int(r), p=int(p),
                             dklen=len(bytes.fromhex(digest)))
    except (ValueError, MemoryError):
        return False
    return hmac.compare_digest(got.hex(), digest)


def check_user_name(name: object) -> str:
    if not isinstance(name, str) or not 1 <= len(name) <= 32 or not set(name) <= _NAME_CHARS:
        raise ValueError(f"user name {name!r} must be 1..32 letters, digits or ._-")
    return name


@dataclass(frozen=True)
class User:
    name: str
    role: str
    password_hash: str


class Users:
    """The users file, checked whole when read (ValueError naming the file, user and key)."""

    def __init__(self, users: dict[str, User], source: str = "<users>") -> None:
        self.users, self.source = dict(users), source
        self._verified: dict[str, User] = {}  # sha256 of accepted credentials → user

    @classmethod
    def load(cls, path: str | Path) -> Users:
        path = Path(path)
        data = read_toml(path, "users file", ValueError, " (make it with `bench station user`)")
        extra = set(data) - {"users"}
        table = data.get("users")
        if extra or not isinstance(table, dict) or not table:
            raise ValueError(f"users file {str(path)!r}: one [users.<name>] table per user, nothing else")
        users = {}
        for name, entry in table.items():
            where = f"users file {str(path)!r}: [users.{name}]"
            try:
                check_user_name(name)
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
            if not isinstance(entry, dict) or set(entry) != {"role", "password"}:
                raise ValueError(f"{where}: needs exactly 'role' and 'password'")
            if entry["role"] not in ROLES:
                raise ValueError(f"{where}: role {entry['role']!r} not in {list(ROLES)}")
            if not isinstance(entry["password"], str) or not entry["password"].startswith("scrypt$"):
                raise ValueError(f"{where}: password must be a scrypt hash written by `bench station "
                                 "user`, never the password itself")
            users[name] = User(name, entry["role"], entry["password"])
        return cls(users, str(path))

    def authenticate(self, authorization: str | None) -> User | None:
        """The user of an ``Authorization: Basic ...`` header, None if it does not log in."""
        if not authorization or not authorization.startswith("Basic "):
            return None
        key = hashlib.sha256(authorization.encode()).hexdigest()
        if key in self._verified:
            return self._verified[key]
        try:
            name, _, password = base64.b64decode(authorization[6:], validate=True).decode().partition(":")
        except (binascii.Error, UnicodeDecodeError):
            return None
        user = self.users.get(name)
        if user is None or not verify_password(password, user.password_hash):
            return None
        self._verified[key] = user
        return user


def add_user(path: str | Path, name: str, role: str, password: str) -> None:
    """Add or replace ``name`` in the users file (created if missing), password hashed."""
    check_user_name(name)
    if role not in ROLES:
        raise ValueError(f"role {role!r} not in {list(ROLES)}")
    if len(password) < MIN_PASSWORD_CHARS:
        raise ValueError(f"password must have at least {MIN_PASSWORD_CHARS} characters")
    path = Path(path)
    users = Users.load(path).users if path.is_file() else {}
    users[name] = User(name, role, hash_password(password))
    lines = ["# operator station users: `bench station user FILE NAME --role ROLE` (scrypt hashes)"]
    for user in users.values():
        lines += ["", f"[users.{json.dumps(user.name)}]", f"role = {json.dumps(user.role)}",
                  f"password = {json.dumps(user.password_hash)}"]
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    os.chmod(tmp, 0o600)
    tmp.replace(path)


Scope = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[MutableMapping[str, Any]]]
Send = Callable[[MutableMapping[str, Any]], Awaitable[None]]


class LoginRequired:
    """ASGI middleware: every HTTP request logs in (Basic) or gets 401; an operator asking
    for an engineer's route gets 403.  The user is ``scope["bench_user"]``."""

    def __init__(self, app: Callable[[Scope, Receive, Send], Awaitable[None]], users: Users) -> None:
        self.app, self.users = app, users

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        header = headers.get(b"authorization", b"").decode("latin-1") or None
        user = self.users.authenticate(header)
        if user is None:
            await _answer(send, 401, "log in: an operator or engineer of this station",
                          [(b"www-authenticate", f'Basic realm="{REALM}", charset="UTF-8"'.encode())])
            return
        if scope.get("path") in ENGINEER_PATHS and user.role != "engineer":
            await _answer(send, 403, f"user {user.name!r} is an {user.role}: the station health "
                          "check is for an engineer")
            return
        scope["bench_user"] = user
        await self.app(scope, receive, send)


async def _answer(send: Send, status: int, error: str, headers: list[tuple[bytes, bytes]] | None = None) -> None:
    body = json.dumps({"error": error}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode()), *(headers or [])]})
    await send({"type": "http.response.body", "body": body})


__all__ = ["ROLES", "ENGINEER_PATHS", "User", "Users", "LoginRequired", "add_user", "hash_password",
           "verify_password", "check_user_name"]
