"""Who may do what on the twin's server: user names and password hashes, trusted user
certificates (bwr_twin.serve.user_certificates), and the rule that only an authenticated user
writes setpoints or calls methods once users are configured.

A users file holds one `name:hash` line per user (blank lines and `#` comments allowed); the hash
is `pbkdf2_sha256$ITERATIONS$SALT$DIGEST` (hex), made by `python -m bwr_twin.serve.passwd NAME`.
Passwords are never stored. A check runs in a worker thread, one at a time
(`Users.verify`, called by `bwr_twin.serve.logins` before asyncua activates a session),
so that the event loop keeps serving clients and hearing signals meanwhile.
"""

from __future__ import annotations

import asyncio
import dataclasses
import hashlib
import hmac
import secrets
from pathlib import Path

from asyncua import ua
from asyncua.common.callback import CallbackType
from asyncua.crypto.permission_rules import USER_TYPES, PermissionRuleset, User, UserRole
from asyncua.server.user_managers import UserManager
from asyncua.ua.ua_binary import struct_from_binary

from bwr_twin.errors import BwrError
from bwr_twin.serve.logins import certificate_login, install_login_checks
from bwr_twin.serve.user_certificates import load_user_certificates, trusted_user
from bwr_twin.textfile import read_text

SCHEME = "pbkdf2_sha256"
# The iterations a users file may ask for. The floor is OWASP's current recommendation for
# PBKDF2-HMAC-SHA256 (600,000); the ceiling keeps one check under a second on the 2-core reference
# machine (0.55-0.73 s measured, loaded; the floor 0.33-0.41 s), so that a file cannot make every
# login a denial of service. 0 or a typo of a few digits is refused at start, not at a login.
MIN_ITERATIONS = 600_000
MAX_ITERATIONS = 1_000_000
ITERATIONS = MIN_ITERATIONS  # what passwd writes
DIGEST_BYTES = 32  # PBKDF2-HMAC-SHA256's digest, as passwd writes it
MIN_SALT_BYTES = 16  # passwd writes 16; NIST SP 800-132 asks for at least 16


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
        lines = read_text(path).splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else exc
        raise SecurityError(f"{path}: cannot read the users file ({reason})") from None
    users: dict[str, str] = {}
    first_lines: dict[str, int] = {}
    for number, line in enumerate(lines, 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, _, stored = line.partition(":")
        fields = stored.split("$")
        if (not name or len(fields) != 4 or fields[0] != SCHEME or not _digits(fields[1])
                or not _hex(fields[2:])):
            raise SecurityError(f"{path}:{number}: expected 'name:{SCHEME}$ITERATIONS$SALT$DIGEST' "
                                "(python -m bwr_twin.serve.passwd NAME makes one)")
        count = fields[1].lstrip("0") or "0"
        if len(count) > len(str(MAX_ITERATIONS)) or not MIN_ITERATIONS <= int(count) <= MAX_ITERATIONS:
            shown = count if len(count) <= 15 else f"a {len(count)}-digit number of"
            raise SecurityError(f"{path}:{number}: user {name!r}: {shown} PBKDF2 iterations; the server "
                                f"takes {MIN_ITERATIONS:,} (OWASP's recommendation for PBKDF2-SHA256) to "
                                f"{MAX_ITERATIONS:,} (a check under 1 s): make the line again with "
                                "python -m bwr_twin.serve.passwd NAME")
        salt, digest = (len(bytes.fromhex(part)) for part in fields[2:])
        if digest != DIGEST_BYTES or salt < MIN_SALT_BYTES:
            raise SecurityError(f"{path}:{number}: user {name!r}: a {salt}-byte salt and a {digest}-byte "
                                f"digest; PBKDF2-SHA256 gives {DIGEST_BYTES} bytes, on a salt of at least "
                                f"{MIN_SALT_BYTES}: make the line again with python -m bwr_twin.serve.passwd NAME")
        if name in users:
            raise SecurityError(f"{path}:{number}: user {name!r} is in the users file twice (first on line "
                                f"{first_lines[name]}); keep one line a user")
        users[name] = stored
        first_lines[name] = number
    if not users:
        raise SecurityError(f"{path}: no users in the users file")
    return users


def _digits(text: str) -> bool:
    return text.isascii() and text.isdigit()


def _hex(parts: list[str]) -> bool:
    try:
        return all(bytes.fromhex(p) for p in parts)
    except ValueError:
        return False


class Users(UserManager):
    """Users of a users file, and holders of a trusted user certificate, may read, write and
    call; an anonymous session, if allowed, reads only.

    asyncua asks `get_user` synchronously, in the event loop; `verify` computes its answer
    beforehand in a worker thread and leaves the verdict for it. Without one (a path asyncua takes
    that `logins` does not see), `get_user` checks in place: bounded by MAX_ITERATIONS. A
    certificate's signature asyncua has checked by then; whether it is trusted is a lookup.
    """

    def __init__(self, users: dict[str, str], certificates: dict | None = None):
        self.users, self.certificates = users, certificates or {}
        self._verdicts: dict[tuple[str, str], bool] = {}
        self._one_at_a_time = asyncio.Semaphore(1)  # a flood of logins queues; it never takes both cores

    async def verify(self, username: str, password: str) -> None:
        """Check a password off the event loop; the verdict waits for the next `get_user`."""
        async with self._one_at_a_time:
            self._verdicts[username, password] = await asyncio.to_thread(self._matches, username, password)

    def forget(self, username: str, password: str) -> None:
        """Drop a verdict `get_user` did not take."""
        self._verdicts.pop((username, password), None)

    def get_user(self, iserver, username=None, password=None, certificate=None) -> User | None:
        if certificate_login.get():  # an X509 token: `certificate` is the user's, its signature checked
            name = trusted_user(self.certificates, certificate)
            return User(role=UserRole.User, name=name) if name is not None else None
        if username is None:  # an anonymous token (on a secure channel `certificate` is the client's own)
            return User(role=UserRole.Anonymous)
        verdict = self._verdicts.pop((username, password), None)
        if verdict is None:
            verdict = self._matches(username, password)
        return User(role=UserRole.User, name=username) if verdict else None  # None: BadUserAccessDenied

    def _matches(self, username: str, password: str | None) -> bool:
        stored = self.users.get(username or "")
        return stored is not None and password is not None and check_password(password, stored)


_WRITE, _CALL = (ua.NodeId(ua.ObjectIds.WriteRequest_Encoding_DefaultBinary),
                 ua.NodeId(ua.ObjectIds.CallRequest_Encoding_DefaultBinary))
_WRITES = {_WRITE, _CALL}
# What any session may call, anonymous included: a SCADA that only watches must still be able to
# ask for the active alarms again (Part 9's ConditionRefresh, bwr_twin.serve.alarms).
ANYONE_CALLS = {ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh),
                ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh2)}


class ReadOnlyAnonymous(PermissionRuleset):
    """Users may do what a client does (never change the address space); anonymous sessions all
    of it but writing and calling methods, ConditionRefresh excepted (ANYONE_CALLS)."""

    def __init__(self):
        allowed = {ua.NodeId(t) for t in USER_TYPES}
        self._allowed = {UserRole.Admin: allowed, UserRole.User: allowed, UserRole.Anonymous: allowed - _WRITES}

    def check_validity(self, user, action_type_id, body) -> bool:
        if action_type_id == _CALL and action_type_id not in self._allowed[user.role] and body is not None:
            return _calls_only(body.copy(), ANYONE_CALLS)
        return action_type_id in self._allowed[user.role]

    async def tell_user_access(self, event, dispatcher=None) -> None:
        """asyncua's PostRead callback: a session reads UserAccessLevel and UserExecutable as
        what it may do (Part 3, 5.6.3 and 5.7), not as the node allows anyone: an anonymous
        session reads no CurrentWrite and UserExecutable false."""
        user, results = event.user, event.response_params
        if user is None:
            return
        may_write, may_call = (self.check_validity(user, request, None) for request in (_WRITE, _CALL))
        for index, read in enumerate(event.request_params.NodesToRead):
            found = results[index]
            if found.Value is None or found.Value.Value is None:
                continue
            if read.AttributeId == ua.AttributeIds.UserAccessLevel and not may_write:
                level = found.Value.Value & ~ua.AccessLevel.CurrentWrite.mask
                results[index] = dataclasses.replace(found, Value=ua.Variant(level, ua.VariantType.Byte))
            elif (read.AttributeId == ua.AttributeIds.UserExecutable and not may_call
                  and read.NodeId not in ANYONE_CALLS):
                results[index] = dataclasses.replace(found, Value=ua.Variant(False, ua.VariantType.Boolean))


def _calls_only(body, methods: set[ua.NodeId]) -> bool:
    """True if the Call request in `body` calls only `methods` (a request that does not parse: False)."""
    try:
        calls = struct_from_binary(ua.CallParameters, body).MethodsToCall
    except Exception:  # noqa: BLE001 - a malformed request is refused, as before
        return False
    return bool(calls) and all(call.MethodId in methods for call in calls)


def encrypt_user_names(server) -> None:
    """Every secured endpoint's UserName token policy names the endpoint's security policy, so that
    a client encrypts the password with the server's certificate (Part 4, 7.41) besides the
    channel's encryption; asyncua would name None there, which asks for the password in clear
    inside the token."""
    add_endpoint = server.iserver.add_endpoint

    def add(endpoint: ua.EndpointDescription) -> None:
        if endpoint.SecurityMode != ua.MessageSecurityMode.None_:
            for token in endpoint.UserIdentityTokens:
                if token.TokenType == ua.UserTokenType.UserName:
                    token.SecurityPolicyUri = endpoint.SecurityPolicyUri
        add_endpoint(endpoint)

    server.iserver.add_endpoint = add


def check_options(*, url: str, loopback: bool, users_file: Path | None, certificate: Path | None,
                  private_key: Path | None, user_certificates: Path | None = None) -> None:
    """SecurityError if the options would serve an address other than loopback open, or name
    files that are not there; asked before any work starts."""
    if (certificate is None) != (private_key is None):
        raise SecurityError("--certificate and --private-key go together")
    if not loopback and ((users_file is None and user_certificates is None) or certificate is None):
        raise SecurityError(f"{url}: an endpoint other than loopback needs --users FILE (or --user-certificates "
                            "PATH) and --certificate/--private-key (Basic256Sha256, signed and encrypted); refusing "
                            "to serve it open")
    if user_certificates is not None and certificate is None:
        raise SecurityError(f"--user-certificates {user_certificates}: needs --certificate and --private-key: a user "
                            "logs in with a certificate by signing the server's (Basic256Sha256)")
    for option, path in (("--users", users_file), ("--certificate", certificate), ("--private-key", private_key)):
        if path is not None and not path.is_file():
            raise SecurityError(f"{option} {path}: no such file")
    if user_certificates is not None and not user_certificates.exists():
        raise SecurityError(f"--user-certificates {user_certificates}: no such file or folder")


async def secure(server, *, url: str, loopback: bool, users_file: Path | None, certificate: Path | None,
                 private_key: Path | None, user_certificates: Path | None = None) -> tuple[list[str], str]:
    """Set the server's security policies, identity tokens and permissions; return the policies'
    names and who may write, for the exposure text.

    Loopback without users: no security, anyone on this machine writes. With users (names and
    passwords, certificates, or both): anonymous sessions read only. Any other address needs
    users and a certificate: Basic256Sha256 with signing and encryption only, so that passwords
    and setpoints never travel in clear.
    """
    check_options(url=url, loopback=loopback, users_file=users_file, certificate=certificate,
                  private_key=private_key, user_certificates=user_certificates)
    if certificate is not None:
        try:
            await server.load_certificate(str(certificate))
            await server.load_private_key(str(private_key))
        except Exception as exc:  # cryptography's errors have no common base
            raise SecurityError(f"{certificate}, {private_key}: not a certificate and its private key "
                                f"({exc})") from None
    if certificate is not None:
        policies, names = [ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt], ["Basic256Sha256 SignAndEncrypt"]
        encrypt_user_names(server)
    else:
        policies, names = [ua.SecurityPolicyType.NoSecurity], ["None (loopback only)"]
    if users_file is None and user_certificates is None:
        server.set_security_policy(policies)
        server.set_identity_tokens([ua.AnonymousIdentityToken])
        return names, "anonymous access: read and write (no --users)"
    users = load_users(users_file) if users_file is not None else {}
    trusted = load_user_certificates(user_certificates) if user_certificates is not None else {}
    install_login_checks()
    server.iserver.set_user_manager(Users(users, trusted))
    permissions = ReadOnlyAnonymous()
    server.set_security_policy(policies, permission_ruleset=permissions)
    server.subscribe_server_callback(CallbackType.PostRead, permissions.tell_user_access)
    tokens, who = [ua.AnonymousIdentityToken], []
    if users:
        tokens.append(ua.UserNameIdentityToken)
        who.append(f"one of the {len(users)} user(s) of {users_file}")
    if trusted:
        tokens.append(ua.X509IdentityToken)
        who.append(f"one of the {len(trusted)} user certificate(s) of {user_certificates}")
    server.set_identity_tokens(tokens)
    return names, f"anonymous access: read only; writes and method calls need {' or '.join(who)}"
