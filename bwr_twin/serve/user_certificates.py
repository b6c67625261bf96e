"""`--user-certificates PATH`: the users who log in with an X.509 certificate (an
X509IdentityToken) instead of a name and password.

PATH is a folder of certificates (`*.pem`, `*.crt`, `*.cer`, `*.der`; other files are ignored)
or one file; a PEM file may hold several. A certificate is trusted as it is, by its exact bytes:
the client proves it holds the private key by signing the server's certificate and nonce
(asyncua checks the signature before the user manager is asked), and the server accepts the
certificate only if it is one of these and within its validity dates at the login.
"""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.x509.oid import NameOID

from bwr_twin.errors import BwrError

SUFFIXES = (".pem", ".crt", ".cer", ".der")


class UserCertificateError(BwrError):
    """A trusted users' certificate file or folder that cannot be read."""


def load_user_certificates(path: Path) -> dict[bytes, x509.Certificate]:
    """DER bytes -> certificate of every trusted user's certificate at `path`. Raises
    UserCertificateError naming the file of one that is not a certificate, or the path if it
    holds none."""
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in SUFFIXES)
    elif path.is_file():
        files = [path]
    else:
        raise UserCertificateError(f"--user-certificates {path}: no such file or folder")
    trusted = {}
    for file in files:
        for certificate in _certificates(file):
            trusted[certificate.public_bytes(serialization.Encoding.DER)] = certificate
    if not trusted:
        raise UserCertificateError(f"--user-certificates {path}: holds no certificate ({', '.join(SUFFIXES)})")
    return trusted


def trusted_user(trusted: dict[bytes, x509.Certificate], certificate_data: bytes | None) -> str | None:
    """The user name (the certificate's common name, else its subject) of a token's
    certificate if it is trusted and valid now, else None. A token may append its chain to the
    certificate: the user's own certificate comes first."""
    if not certificate_data:
        return None
    for der, certificate in trusted.items():
        if certificate_data[:len(der)] == der:
            now = datetime.now(timezone.utc)
            if not certificate.not_valid_before_utc <= now <= certificate.not_valid_after_utc:
                return None
            names = certificate.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
            return str(names[0].value) if names else certificate.subject.rfc4514_string()
    return None


def _certificates(file: Path) -> list[x509.Certificate]:
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise UserCertificateError(f"--user-certificates {file}: cannot read it ({exc.strerror})") from None
    if b"PRIVATE KEY-----" in data:
        raise UserCertificateError(f"--user-certificates {file}: holds a private key; the server needs the users' "
                                   "certificates only (the key stays with its user)")
    try:
        if b"-----BEGIN CERTIFICATE-----" in data:
            return x509.load_pem_x509_certificates(data)
        return [x509.load_der_x509_certificate(data)]
    except ValueError:
        raise UserCertificateError(f"--user-certificates {file}: not an X.509 certificate (PEM or DER)") from None
