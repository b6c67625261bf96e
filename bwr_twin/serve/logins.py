"""Password checks off the event loop.

asyncua activates a session synchronously, and asks the user manager for the user inside that
call: a PBKDF2 check there holds the whole server (other clients, the real-time clock, SIGTERM
and Ctrl-C) for as long as it takes. The processor below sees an ActivateSession request first,
has the user manager check its password in a worker thread (`Users.verify`), and only
then hands the request to asyncua, whose `get_user` finds the verdict waiting.

asyncua calls `get_user` with no user name both for an anonymous session on a secure channel
(with the channel's client certificate) and for a user certificate (an X509IdentityToken): the
processor says which it is, in `certificate_login`, while asyncua handles the request.
"""

from __future__ import annotations

from contextvars import ContextVar

from asyncua import ua
from asyncua.server import binary_server_asyncio
from asyncua.server.uaprocessor import UaProcessor
from asyncua.ua.ua_binary import nodeid_from_binary, struct_from_binary

_ACTIVATE = ua.NodeId(ua.ObjectIds.ActivateSessionRequest_Encoding_DefaultBinary)

# True while asyncua activates a session whose user identity token is a certificate.
certificate_login: ContextVar[bool] = ContextVar("certificate_login", default=False)


class CheckingProcessor(UaProcessor):
    """asyncua's processor of one connection, with password checks done before activation."""

    async def process_message(self, seqhdr, body):
        if _token(body.copy()) is ua.X509IdentityToken:
            flag = certificate_login.set(True)  # this connection's task only
            try:
                return await super().process_message(seqhdr, body)
            finally:
                certificate_login.reset(flag)
        manager = self.iserver.user_manager
        login = self._login(body.copy()) if hasattr(manager, "verify") else None
        if login is None:
            return await super().process_message(seqhdr, body)
        await manager.verify(*login)
        try:
            return await super().process_message(seqhdr, body)
        finally:
            manager.forget(*login)  # a verdict asyncua did not ask for (it refused the request before) goes

    def _login(self, body) -> tuple[str, str] | None:
        """(user name, password) of an ActivateSession request with a user name token, else None
        (anything else, or a request asyncua itself will refuse, goes to asyncua untouched)."""
        try:
            if nodeid_from_binary(body) != _ACTIVATE:
                return None
            header = struct_from_binary(ua.RequestHeader, body)
            token = struct_from_binary(ua.ActivateSessionParameters, body).UserIdentityToken
            if not isinstance(token, ua.UserNameIdentityToken):
                return None
            session = self.session or self.iserver.lookup_external_session(header.AuthenticationToken)
            if session is None:
                return None
            username, password = self.iserver.decrypt_user_token(session, token)
        except Exception:  # noqa: BLE001 - a malformed request is asyncua's to answer
            return None
        return (username, password) if isinstance(username, str) and isinstance(password, str) else None


def _token(body) -> type | None:
    """The type of the user identity token of an ActivateSession request, else None."""
    try:
        if nodeid_from_binary(body) != _ACTIVATE:
            return None
        struct_from_binary(ua.RequestHeader, body)
        return type(struct_from_binary(ua.ActivateSessionParameters, body).UserIdentityToken)
    except Exception:  # noqa: BLE001 - a malformed request is asyncua's to answer
        return None


def install_login_checks() -> None:
    """Make every connection the server accepts from now on use CheckingProcessor."""
    binary_server_asyncio.UaProcessor = CheckingProcessor

