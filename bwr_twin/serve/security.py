"""Who may do what on the twin's server: user names and password hashes, and the rule that only
an authenticated user writes setpoints or calls methods once users are configured.

A users file holds one `name:hash` line per user (blank lines and `#` comments allowed); the hash
is `pbkdf2_sha256$ITERATIONS$SALT$DIGEST` (hex), made by `python -m bwr_twin.serve.passwd NAME`.
Passwords are never stored.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from pathlib import Path

from asyncua import ua
from asyncua.crypto.permission_rules import USER_TYPES, PermissionRuleset, User, UserRole
from asyncua.server.user_managers import UserManager

from bwr_twin.errors import BwrError

SCHEME = "pbkdf2_sha256"
ITERATIONS = 100_000  # about 54 ms a check here: cheap for a login, dear for guessing


class SecurityError(BwrError):
    """A users file, certificate or endpoint that the server cannot serve securely."""


def hash_password(password: str, *, iterations: int = ITERATIONS, salt: bytes | None = None) -> str:
    """The users file's hash of `password`."""
    salt = secrets.token_bytes(16) if salt is None else salt
    digest = hashlib.pbkdf2_hmac("sha256", password.encode(), salt, iterations)
    return f"{SCHEME}${iterations}${salt.hex()}${digest.hex()}"


def check_password(password: str, stored: str) -> bool:
    """True if `password` matches a hash of `hash_password`."""
    _, iterations, salt, digest = stored.split("$")
    candidate = hashlib.pbkdf2_hmac("sha256", password.encode(), bytes.fromhex(salt), int(iterations))
    return hmac.compare_digest(candidate.hex(), digest)


def load_users(path: Path) -> dict[str, str]:
    """name -> hash from a users file. Raises SecurityError naming the file and line of a bad entry."""
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else exc
        raise SecurityError(f"{path}: cannot read the users file ({reason})") from None
    users: dict[str, str] = {}
    for number, line in enumerate(lines, 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, _, stored = line.partition(":")
        fields = stored.split("$")
        if not name or len(fields) != 4 or fields[0] != SCHEME or not fields[1].isdigit() or not _hex(fields[2:]):
            raise SecurityError(f"{path}:{number}: expected 'name:{SCHEME}$ITERATIONS$SALT$DIGEST' "
                                "(python -m bwr_twin.serve.passwd NAME makes one)")
        users[name] = stored
    if not users:
        raise SecurityError(f"{path}: no users in the users file")
    return users


def _hex(parts: list[str]) -> bool:
    try:
        return all(bytes.fromhex(p) for p in parts)
    except ValueError:
        return False


class PasswordUsers(UserManager):
    """Users of a users file may read, write and call; an anonymous session, if allowed, reads only."""

    def __init__(self, users: dict[str, str]):
        self.users = users

    def get_user(self, iserver, username=None, password=None, certificate=None) -> User | None:
        if username is None:  # an anonymous token (on a secure channel `certificate` is the client's own)
            return User(role=UserRole.Anonymous)
        stored = self.users.get(username or "")
        if stored is not None and password is not None and check_password(password, stored):
            return User(role=UserRole.User, name=username)
        return None  # asyncua answers BadUserAccessDenied


_WRITES = {ua.NodeId(ua.ObjectIds.WriteRequest_Encoding_DefaultBinary),
           ua.NodeId(ua.ObjectIds.CallRequest_Encoding_DefaultBinary)}


class ReadOnlyAnonymous(PermissionRuleset):
    """Users may do what a client does (never change the address space); anonymous sessions all
    of it but writing and calling methods."""

    def __init__(self):
        allowed = {ua.NodeId(t) for t in USER_TYPES}
        self._allowed = {UserRole.Admin: allowed, UserRole.User: allowed, UserRole.Anonymous: allowed - _WRITES}

    def check_validity(self, user, action_type_id, body) -> bool:
        return action_type_id in self._allowed[user.role]


def check_options(*, url: str, loopback: bool, users_file: Path | None, certificate: Path | None,
                  private_key: Path | None) -> None:
    """SecurityError if the options would serve an address other than loopback open, or name
    files that are not there; asked before any work starts."""
    if (certificate is None) != (private_key is None):
        raise SecurityError("--certificate and --private-key go together")
    if not loopback and (users_file is None or certificate is None):
        raise SecurityError(f"{url}: an endpoint other than loopback needs --users FILE and --certificate/"
                            "--private-key (Basic256Sha256, signed and encrypted); refusing to serve it open")
    for option, path in (("--users", users_file), ("--certificate", certificate), ("--private-key", private_key)):
        if path is not None and not path.is_file():
            raise SecurityError(f"{option} {path}: no such file")


async def secure(server, *, url: str, loopback: bool, users_file: Path | None, certificate: Path | None,
                 private_key: Path | None) -> tuple[list[str], str]:
    """Set the server's security policies, identity tokens and permissions; return the policies'
    names and who may write, for the exposure text.

    Loopback without users: no security, anyone on this machine writes. With users: anonymous
    sessions read only. Any other address needs users and a certificate: Basic256Sha256 with
    signing and encryption only, so that passwords and setpoints never travel in clear.
    """
    check_options(url=url, loopback=loopback, users_file=users_file, certificate=certificate,
                  private_key=private_key)
    if certificate is not None:
        try:
            await server.load_certificate(str(certificate))
            await server.load_private_key(str(private_key))
        except Exception as exc:  # cryptography's errors have no common base
            raise SecurityError(f"{certificate}, {private_key}: not a certificate and its private key "
                                f"({exc})") from None
    if certificate is not None:
        policies, names = [ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt], ["Basic256Sha256 SignAndEncrypt"]
    else:
        policies, names = [ua.SecurityPolicyType.NoSecurity], ["None (loopback only)"]
    if users_file is None:
        server.set_security_policy(policies)
        server.set_identity_tokens([ua.AnonymousIdentityToken])
        return names, "anonymous access: read and write (no --users)"
    users = load_users(users_file)
    server.iserver.set_user_manager(PasswordUsers(users))
    server.set_security_policy(policies, permission_ruleset=ReadOnlyAnonymous())
    server.set_identity_tokens([ua.AnonymousIdentityToken, ua.UserNameIdentityToken])
    return names, (f"anonymous access: read only; writes and method calls need one of the {len(users)} "
                   f"user(s) of {users_file}")
