"""`horus remote`: reach a robot from afar over Cap'n Proto RPC with mutual TLS (docs/remote.md).

keygen makes the link's certificates: DIR holds one CA (ca.key, ca.crt, made by the first run)
and, per NAME, NAME.key and NAME.crt signed by that CA, with NAME as the certificate's common name
(what a robot's policy names peers by) and as its DNS name (what a peer checks the robot's
certificate against); keys are mode 0600. status reads the status files of the namespace's
horus-remote processes; serve and connect run horus-remote (bridges/remote). The cryptography
package is imported by keygen alone, so that every other command starts without it.
"""
from __future__ import annotations

import argparse
import datetime
import os
import pathlib
from typing import TYPE_CHECKING

from horus_cli.common import (EXIT_OK, CommandFailed, emit, introspection, live_status_files,
                               table)

if TYPE_CHECKING:
    from cryptography import x509

AUTHORITY_YEARS = 20
PEER_YEARS = 10


def _write_key(path: pathlib.Path, key) -> None:
    from cryptography.hazmat.primitives import serialization
    data = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(descriptor, "wb") as file:
        file.write(data)


def _write_certificate(path: pathlib.Path, certificate) -> None:
    from cryptography.hazmat.primitives import serialization
    path.write_bytes(certificate.public_bytes(serialization.Encoding.PEM))


def _signed(subject: x509.Name, public_key, issuer: x509.Name, signing_key, years: int,
            extensions) -> x509.Certificate:
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes
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
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID
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
    from cryptography import x509
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
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


# Set by the launcher (bin/horus) to the horus-remote beside it (`horus remote serve|connect`).
REMOTE_PROGRAM = os.environ.get("HORUS_REMOTE_PROGRAM", "horus-remote")


def remote_keygen(args) -> int:
    try:
        refused = keygen(args.folder, args.names)
    except (OSError, ValueError) as error:
        raise CommandFailed(str(error)) from None
    if refused:
        raise CommandFailed("; ".join(refused))
    return EXIT_OK


def remote_status(args) -> int:
    """The streams of the namespace's horus-remote processes, from the status file each writes
    every second (bridges/remote: status_path)."""
    namespace = args.namespace or introspection().current_namespace()
    rows = [{"pid": status["pid"], "role": status["role"], **stream}
            for status in live_status_files("horus-remote", namespace)
            for stream in status["streams"]]

    def render(rows):
        if not rows:
            print(f"no horus remote streams in namespace '{namespace}'")
            return
        table(["PID", "ROLE", "STREAM", "SENT", "DROPPED"],
              [[r["pid"], r["role"], r["stream"], r["sent"], r["dropped"]] for r in rows])
    emit(rows, args.json, render)
    return EXIT_OK


def remote_link(args) -> int:
    # The namespace reaches horus-remote through HORUS_NAMESPACE, which main() set.
    try:
        os.execvp(REMOTE_PROGRAM, [REMOTE_PROGRAM, args.action, *args.remote_args])
    except OSError as error:
        raise CommandFailed(f"cannot run {REMOTE_PROGRAM}: {error.strerror}") from None


def register(commands) -> None:
    remote = commands.group("remote", "reach a robot from afar over Cap'n Proto RPC with mutual "
                                      "TLS (docs/remote.md)")
    sub = commands.action(remote, "keygen", "make a CA in DIR (once) and a key and certificate "
                          "signed by it per NAME (the certificate's name)", remote_keygen,
                          json_output=False)
    sub.add_argument("folder", metavar="DIR")
    sub.add_argument("names", metavar="NAME", nargs="+")
    commands.action(remote, "status", "the streams of this namespace's horus remote processes: "
                    "messages sent and dropped (latest wins on a slow link)", remote_status)
    for name, help_text in (("serve", "serve this namespace to authenticated peers (runs "
                                      "horus-remote serve; --help lists its options)"),
                            ("connect", "mirror a robot's topics, parameters and frames here and "
                                        "send ours to it (runs horus-remote connect; --help lists "
                                        "its options)")):
        # '+' as the prefix: every argument, options too, goes to horus-remote as it is.
        sub = remote.add_parser(name, help=help_text, description=help_text, prefix_chars="+",
                                add_help=False)
        sub.add_argument("remote_args", nargs=argparse.REMAINDER)
        sub.set_defaults(handler=remote_link)
