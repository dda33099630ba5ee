"""What the client and the study tool take from their user, refused before anything is sent:
addresses whose port gRPC would wrap, files without a bound (a CA bundle, a token file, a
spec), empty tokens that would mean "no auth" in silence. Each refusal names the file or the
value and the limit. No foamd is needed."""

import os
import time

import pytest

from activefoam import Client, Job
from activefoam.inputs import read_bounded, read_token_file

CERT = "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n"


@pytest.fixture(autouse=True)
def _no_env(monkeypatch):
    for k in ("FOAM_SERVER", "FOAM_TOKEN", "FOAM_TLS_CA"):
        monkeypatch.delenv(k, raising=False)


@pytest.mark.parametrize("server, words", [
    ("127.0.0.1:87366", "'127.0.0.1:87366': the port 87366 is outside 1..65535"),
    ("127.0.0.1:0", "the port 0 is outside 1..65535"),
    ("127.0.0.1:65536", "the port 65536 is outside"),
    ("127.0.0.1:-1", "the port '-1' is not a number"),
    ("127.0.0.1:", "the port '' is not a number"),
    ("127.0.0.1:5e4", "the port '5e4' is not a number"),
    ("localhost", "'localhost' is not HOST:PORT"),
    (":50051", "is not HOST:PORT"),
    ("::1:50051", "an IPv6 host needs brackets"),
])
def test_a_port_outside_1_to_65535_is_refused_naming_the_address(server, words):
    # gRPC took the port modulo 65536: 87366 connected to 21830 and sent the token there.
    with pytest.raises(ValueError, match="server: ") as e:
        Client(server, token="a-good-token-0123456789")
    assert words in str(e.value)


def test_foam_server_is_checked_and_named(monkeypatch):
    monkeypatch.setenv("FOAM_SERVER", "127.0.0.1:87366")
    with pytest.raises(ValueError, match="FOAM_SERVER: '127.0.0.1:87366': the port 87366"):
        Client()


@pytest.mark.parametrize("server", ["127.0.0.1:1", "127.0.0.1:65535", "[::1]:50051",
                                    "localhost:50051"])
def test_addresses_in_range_are_taken(server):
    Client(server).close()


def test_an_empty_foam_token_is_an_error_not_no_auth(monkeypatch):
    monkeypatch.setenv("FOAM_TOKEN", "")
    with pytest.raises(ValueError, match="FOAM_TOKEN holds 0 bytes"):
        Client("127.0.0.1:1")
    with pytest.raises(ValueError, match="token holds 0 bytes"):
        Client("127.0.0.1:1", token="")
    monkeypatch.setenv("FOAM_TOKEN", "has a space in it 0123")
    with pytest.raises(ValueError, match="FOAM_TOKEN has byte 0x20 at offset 3"):
        Client("127.0.0.1:1")


def _refused_fast(call, words):
    t0 = time.monotonic()
    with pytest.raises(ValueError) as e:
        call()
    assert time.monotonic() - t0 < 1.0
    for w in words:
        assert w in str(e.value), str(e.value)


def test_a_ca_bundle_is_a_bounded_regular_file_holding_a_certificate(tmp_path):
    _refused_fast(lambda: Client("127.0.0.1:1", tls_ca="/dev/zero"),
                  ["tls_ca '/dev/zero'", "not a regular file"])
    big = tmp_path / "big.pem"
    big.write_text(CERT + "x" * (1 << 20))
    _refused_fast(lambda: Client("127.0.0.1:1", tls_ca=str(big)),
                  [f"tls_ca '{big}' holds {big.stat().st_size} bytes", "1 MiB"])
    junk = tmp_path / "junk.pem"
    junk.write_text("not a certificate\n")
    _refused_fast(lambda: Client("127.0.0.1:1", tls_ca=str(junk)),
                  [f"tls_ca '{junk}': not a PEM certificate"])
    _refused_fast(lambda: Client("127.0.0.1:1", tls_ca=str(tmp_path / "none.pem")),
                  ["no such file"])
    _refused_fast(lambda: Client("127.0.0.1:1", tls_ca=""), ["tls_ca ''"])
    ok = tmp_path / "ok.pem"
    ok.write_text(CERT)
    Client("127.0.0.1:1", tls_ca=str(ok)).close()


def test_foam_tls_ca_is_named(tmp_path, monkeypatch):
    monkeypatch.setenv("FOAM_TLS_CA", "/dev/zero")
    _refused_fast(lambda: Client("127.0.0.1:1"), ["FOAM_TLS_CA '/dev/zero'"])


def _token_file(tmp_path, content, mode=0o600):
    f = tmp_path / "token"
    f.write_bytes(content)
    f.chmod(mode)
    return f


def test_a_token_file_is_read_as_foam_reads_it(tmp_path):
    assert read_token_file(_token_file(tmp_path, b"  a-good-token-0123456789\n")) == \
        "a-good-token-0123456789"
    _refused_fast(lambda: read_token_file("/dev/zero"),
                  ["token file '/dev/zero': not a readable file"])
    f = _token_file(tmp_path, b"\n")
    _refused_fast(lambda: read_token_file(f), [f"token file '{f}' holds 0 bytes"])
    f = _token_file(tmp_path, b"x" * (64 << 10))
    _refused_fast(lambda: read_token_file(f), [f"token file '{f}' holds 65536 bytes",
                                               "16 KiB"])
    f = _token_file(tmp_path, b"a-good-token-0123456789", mode=0o644)
    _refused_fast(lambda: read_token_file(f), ["accessible to other users (mode 0644)",
                                               f"chmod 600 '{f}'"])
    _refused_fast(lambda: read_token_file(""), ["token file '': an empty path"])


def test_a_file_without_a_size_is_read_to_its_cap_plus_one_byte():
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="spec '/dev/zero' holds more than the 1 MiB"):
        read_bounded("/dev/zero", 1 << 20, "spec")
    assert time.monotonic() - t0 < 1.0
    r, w = os.pipe()
    os.write(w, b"x" * 10)
    os.close(w)
    assert read_bounded(f"/dev/fd/{r}", 10, "spec") == b"x" * 10
    os.close(r)


@pytest.mark.parametrize("fps", [float("nan"), float("inf"), 0, -1, "4", True])
def test_a_movie_rate_that_is_no_rate_is_refused_before_foam_runs(fps, tmp_path):
    with pytest.raises(ValueError, match="fps: a positive number"):
        Job(Client("127.0.0.1:1"), "j-x").movie(tmp_path / "m.mp4", fps=fps, foam="/nonexistent")
