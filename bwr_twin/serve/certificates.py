"""The server's certificate and private key, checked before the server starts.

A key that is not the certificate's, or a certificate that does not name the server's
application URI, is accepted by asyncua and only shows when every secure client times out or
refuses the server: both are refused here, in one line naming the files.
"""

from __future__ import annotations

from pathlib import Path

from cryptography import x509
from cryptography.exceptions import UnsupportedAlgorithm
from cryptography.hazmat.primitives import serialization

from bwr_twin.errors import BwrError


class CertificateError(BwrError):
    """A server certificate or private key the secure endpoint cannot use."""


def check_certificate(certificate: Path, private_key: Path, application_uri: str) -> None:
    """CertificateError unless `certificate` (DER or PEM) holds the public key of `private_key`
    (PEM or DER, unencrypted) and names `application_uri` in its subjectAltName."""
    cert = _certificate(certificate)
    key = _private_key(private_key)
    if _public(key.public_key()) != _public(cert.public_key()):
        raise CertificateError(f"--private-key {private_key} does not match --certificate {certificate}: the "
                               "key's public key is not the certificate's (give the key the certificate was made "
                               "with)")
    try:
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        uris = names.get_values_for_type(x509.UniformResourceIdentifier)
    except x509.ExtensionNotFound:
        uris = []
    if application_uri not in uris:
        found = f"it names {', '.join(uris)}" if uris else "it names no URI"
        raise CertificateError(f"--certificate {certificate}: its subjectAltName must name the URI "
                               f"{application_uri}, the server's application URI that clients check; {found} "
                               "(docs/opcua.md)")


def _certificate(path: Path) -> x509.Certificate:
    data = _read(path, "--certificate")
    for load in (x509.load_pem_x509_certificate, x509.load_der_x509_certificate):
        try:
            return load(data)
        except ValueError:
            continue
    raise CertificateError(f"--certificate {path}: not an X.509 certificate (PEM or DER)")


def _private_key(path: Path):
    data = _read(path, "--private-key")
    for load in (serialization.load_pem_private_key, serialization.load_der_private_key):
        try:
            return load(data, password=None)
        except TypeError:  # encrypted: the server has no one to ask for its passphrase
            raise CertificateError(f"--private-key {path}: encrypted; the server needs it unencrypted "
                                   "(openssl pkey -in KEY -out KEY_PLAIN)") from None
        except (ValueError, UnsupportedAlgorithm):
            continue
    raise CertificateError(f"--private-key {path}: not a private key (PEM or DER)")


def _read(path: Path, option: str) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise CertificateError(f"{option} {path}: cannot read it ({exc.strerror})") from None


def _public(key) -> bytes:
    return key.public_bytes(serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)
