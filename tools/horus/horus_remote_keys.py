"""`horus remote keygen DIR NAME...`: the certificates of the remote link (docs/remote.md). DIR
holds one CA (ca.key, ca.crt, made by the first run) and, per NAME, NAME.key and NAME.crt signed
by that CA, with NAME as the certificate's common name (what a robot's policy names peers by)
and as its DNS name (what a peer checks the robot's certificate against). Keys are mode 0600."""
from __future__ import annotations

import datetime
import os
import pathlib

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

AUTHORITY_YEARS = 20
PEER_YEARS = 10


def _write_key(path: pathlib.Path, key) -> None:
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "wb") as file:
        file.write(data)


def _write_certificate(path: pathlib.Path, certificate) -> None:
    path.write_bytes(certificate.public_bytes(serialization.Encoding.PEM))


def _signed(subject: x509.Name, public_key, issuer: x509.Name, signing_key, years: int,
            extensions) -> x509.Certificate:
    now = datetime.datetime.now(datetime.timezone.utc)
    builder = (x509.CertificateBuilder().subject_name(subject).issuer_name(issuer)
               .public_key(public_key).serial_number(x509.random_serial_number())
               .not_valid_before(now - datetime.timedelta(minutes=5))
               .not_valid_after(now + datetime.timedelta(days=365 * years)))
    for extension, critical in extensions:
        builder = builder.add_extension(extension, critical=critical)
    return builder.sign(signing_key, hashes.SHA256())


def _authority(folder: pathlib.Path):
    """The folder's CA (key, certificate), made on the first call."""
    key_path, certificate_path = folder / "ca.key", folder / "ca.crt"
    if certificate_path.exists():
        key = serialization.load_pem_private_key(key_path.read_bytes(), password=None)
        return key, x509.load_pem_x509_certificate(certificate_path.read_bytes())
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, f"HORUS remote CA {folder.name}")])
    certificate = _signed(name, key.public_key(), name, key, AUTHORITY_YEARS, [
        (x509.BasicConstraints(ca=True, path_length=0), True),
        (x509.KeyUsage(digital_signature=False, content_commitment=False, key_encipherment=False,
                       data_encipherment=False, key_agreement=False, key_cert_sign=True,
                       crl_sign=True, encipher_only=False, decipher_only=False), True)])
    _write_key(key_path, key)
    _write_certificate(certificate_path, certificate)
    print(f"made the CA {certificate_path}")
    return key, certificate


def keygen(folder_name: str, names: list[str]) -> list[str]:
    """Makes the CA of `folder_name` (once) and a key and certificate per name; the reasons for
    the names it refused (a bad name, or one that has a certificate already)."""
    folder = pathlib.Path(folder_name)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    refused = []
    for name in names:
        if not name or "/" in name or name == "ca" or name.startswith("."):
            refused.append(f"'{name}' cannot name a certificate")
        elif (folder / f"{name}.crt").exists() or (folder / f"{name}.key").exists():
            refused.append(f"{folder / name}.crt exists: delete {name}.crt and {name}.key "
                           "to make new ones")
    if refused:
        return refused
    authority_key, authority = _authority(folder)
    for name in names:
        key = ec.generate_private_key(ec.SECP256R1())
        certificate = _signed(
            x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]), key.public_key(),
            authority.subject, authority_key, PEER_YEARS, [
                (x509.BasicConstraints(ca=False, path_length=None), True),
                (x509.SubjectAlternativeName([x509.DNSName(name)]), False),
                (x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                        ExtendedKeyUsageOID.CLIENT_AUTH]), False)])
        _write_key(folder / f"{name}.key", key)
        _write_certificate(folder / f"{name}.crt", certificate)
        print(f"made {folder / name}.key and {name}.crt (CN {name})")
    return []
