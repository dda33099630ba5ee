"""What the client and the study tool take from their user: files read to a cap, bearer tokens
and HOST:PORT addresses, checked as foam checks them (common/include/activefoam/), each refusal
a ValueError naming the file or value and the limit."""

from __future__ import annotations

import os
import stat
from typing import Union

SPEC_MAX_BYTES = 1 << 20          # a spec, a study file, a study's base (foam-run's cap)
PEM_MAX_BYTES = 1 << 20           # a CA bundle (foam --tls-ca)
MIN_TOKEN_BYTES, MAX_TOKEN_BYTES = 16, 4096
TOKEN_FILE_MAX_BYTES = 4 * MAX_TOKEN_BYTES  # a token and its surrounding whitespace, as foam


def _size(n: int) -> str:
    return f"{n >> 20} MiB" if n >= 1 << 20 and n % (1 << 20) == 0 else (
        f"{n >> 10} KiB" if n % 1024 == 0 else f"{n} bytes")


def read_bounded(path: Union[str, os.PathLike], cap: int, what: str,
                 regular: bool = False) -> bytes:
    """The bytes of `path`, at most `cap` of them: a larger file is refused, and a file without
    a size (a device, a pipe) is read to cap + 1 bytes at most, so /dev/zero is refused at once.
    `regular`: only a regular file (symlinks followed). ValueError says "WHAT 'PATH' ..."."""
    name = f"{what} '{os.fspath(path)}'"
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ValueError(f"{name}: no such file") from None
    except OSError as e:
        raise ValueError(f"{name}: {e.strerror}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{name} is a directory, not a file")
    if regular and not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{name}: not a regular file")
    if stat.S_ISREG(st.st_mode) and st.st_size > cap:
        raise ValueError(f"{name} holds {st.st_size} bytes, more than the {_size(cap)} it may "
                         "have")
    try:
        with open(path, "rb") as f:
            data = f.read(cap + 1)
    except OSError as e:
        raise ValueError(f"{name}: {e.strerror}") from None
    if len(data) > cap:
        raise ValueError(f"{name} holds more than the {_size(cap)} it may have")
    return data


def token_error(token: Union[str, bytes]) -> str:
    """"" when `token` can be a bearer token (16..4096 bytes of printable ASCII without spaces:
    what gRPC metadata carries as it is); otherwise what is wrong, in foam's words."""
    data = token.encode("utf-8", "surrogateescape") if isinstance(token, str) else token
    if len(data) < MIN_TOKEN_BYTES:
        return f"holds {len(data)} bytes; a token needs at least {MIN_TOKEN_BYTES}"
    if len(data) > MAX_TOKEN_BYTES:
        return f"holds {len(data)} bytes; a token has at most {MAX_TOKEN_BYTES}"
    for i, b in enumerate(data):
        if not 0x21 <= b <= 0x7E:
            return f"has byte 0x{b:02x} at offset {i}: a token is printable ASCII without spaces"
    return ""


def read_token_file(path: Union[str, os.PathLike]) -> str:
    """The token in a file (surrounding whitespace removed), read as foam reads --token-file: a
    regular file that only its owner may read, at most 16 KiB. An empty file, or an empty path,
    is an error, not "no token". ValueError names the file."""
    name = f"token file '{os.fspath(path)}'"
    if not os.fspath(path):
        raise ValueError(f"{name}: an empty path (leave the option out for no token)")
    try:
        st = os.stat(path)
    except OSError:
        raise ValueError(f"{name}: not a readable file") from None
    if not stat.S_ISREG(st.st_mode):
        raise ValueError(f"{name}: not a readable file")
    if st.st_mode & 0o077:
        raise ValueError(f"{name} is accessible to other users (mode "
                         f"{st.st_mode & 0o7777:04o}): chmod 600 '{os.fspath(path)}'")
    data = read_bounded(path, TOKEN_FILE_MAX_BYTES, "token file", regular=True)
    token = data.strip(b" \t\n\r\v\f")
    bad = token_error(token)
    if bad:
        raise ValueError(f"{name} {bad} (e.g. head -c 24 /dev/urandom | base64 > "
                         f"'{os.fspath(path)}')")
    return token.decode("ascii")


def host_port_error(hostport: str) -> str:
    """"" when `hostport` is HOST:PORT (HOST a name, an IPv4 address or [IPv6]) with PORT in
    1..65535; otherwise what is wrong. gRPC takes a port modulo 65536: 127.0.0.1:87366 would
    connect to 21830 and hand that port the token."""
    colon = hostport.rfind(":")
    if colon <= 0:
        return f"'{hostport}' is not HOST:PORT"
    host, port = hostport[:colon], hostport[colon + 1:]
    if not host.startswith("[") and ":" in host:
        return f"'{hostport}': an IPv6 host needs brackets, e.g. [::1]:50051"
    if not port or len(port) > 5 or not all("0" <= c <= "9" for c in port):
        return f"'{hostport}': the port '{port}' is not a number in 1..65535"
    if not 1 <= int(port) <= 65535:
        return f"'{hostport}': the port {port} is outside 1..65535"
    return ""


def read_certificates(path: Union[str, os.PathLike], what: str) -> bytes:
    """A PEM file of certificates (a server's certificate or its CA), as foam reads --tls-ca: a
    regular file of at most 1 MiB holding a certificate."""
    data = read_bounded(path, PEM_MAX_BYTES, what, regular=True)
    if b"-----BEGIN CERTIFICATE-----" not in data:
        raise ValueError(f"{what} '{os.fspath(path)}': not a PEM certificate (no "
                         "'-----BEGIN CERTIFICATE-----' line)")
    return data


def read_text(path: Union[str, os.PathLike], cap: int, what: str,
              regular: bool = False) -> str:
    """read_bounded, decoded as UTF-8; a file that is not says which byte."""
    data = read_bounded(path, cap, what, regular)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{what} '{os.fspath(path)}' is not UTF-8 (byte {e.start})") from None


__all__ = ["SPEC_MAX_BYTES", "PEM_MAX_BYTES", "MIN_TOKEN_BYTES", "MAX_TOKEN_BYTES",
           "TOKEN_FILE_MAX_BYTES", "read_bounded", "read_text", "token_error",
           "read_token_file", "host_port_error", "read_certificates"]
