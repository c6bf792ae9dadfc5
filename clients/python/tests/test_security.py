"""A reliefd that wants bearer tokens and speaks TLS: the token on every
call (unary and streams, sync and asyncio), read and control scopes as
Unauthenticated and PermissionDenied, RELIEF_TOKEN and RELIEF_CA, a CA of
the test's own, and how addresses, CAs and tokens are read."""

from __future__ import annotations

import asyncio
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

import relief
import relief.aio
from relief import _channel
from relief.testing import (
    Certificates,
    Reliefd,
    TokenFile,
    make_certificates,
    write_token_file,
)

PEAK = (10.25, 45.25)
CAMERA = relief.Camera(lon_deg=10.25, lat_deg=45.12, altitude_m=9000, pitch_deg=-45)
SIZE = (64, 48)


@pytest.fixture
def tokens(tmp_path: Path) -> TokenFile:
    return write_token_file(tmp_path / "secrets")


@pytest.fixture
def reliefd_args(tokens: TokenFile) -> tuple[str, ...]:
    """The plugin's `reliefd` fixture serves with this token file."""
    return tokens.args


@pytest.fixture
def relief_token(tokens: TokenFile) -> str:
    """The plugin's `relief_client` fixture sends the read token."""
    return tokens.read


@pytest.fixture(scope="module")
def secure(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Reliefd, TokenFile, Certificates]]:
    """One reliefd with tokens and TLS for the TLS tests."""
    from relief.testing import write_hill_scene

    folder = tmp_path_factory.mktemp("secure")
    scene = write_hill_scene(folder / "scene")
    tokens = write_token_file(folder / "secrets")
    certs = make_certificates(folder / "tls")
    with Reliefd(scene.manifest, args=(*tokens.args, *certs.args)) as daemon:
        assert daemon.tls, daemon.viewer_url
        yield daemon, tokens, certs


# ------------------------------------------------------------ tokens


def test_no_token_or_a_wrong_one_is_unauthenticated(reliefd: Reliefd) -> None:
    with reliefd.connect() as client:
        with pytest.raises(relief.Unauthenticated, match="missing token") as caught:
            client.state()
        assert caught.value.code == "UNAUTHENTICATED" and caught.value.method == "GetState"
        with pytest.raises(relief.Unauthenticated), client.events() as events:
            next(iter(events))
    with reliefd.connect(token="read-0123456789abcdeX") as client:
        with pytest.raises(relief.Unauthenticated, match="not one this reliefd accepts"):
            client.elevation([PEAK])


def test_a_read_token_reads_and_may_not_steer(relief_client: relief.Client, reliefd: Reliefd) -> None:
    state = relief_client.state()
    assert state.name == "hill"
    assert relief_client.elevation([PEAK]) == [pytest.approx(2000.0, abs=1.0)]
    col, row = state.grid.tile_at(9, *PEAK)
    assert relief_client.tile("dem", 9, col, row, expect=relief.HeightTile).heights.size > 0
    assert relief_client.render(CAMERA, size=SIZE).to_numpy().shape == (SIZE[1], SIZE[0], 4)
    with relief_client.events() as events:
        assert isinstance(next(iter(events)), relief.SnapshotEvent)
    with relief_client.frames(CAMERA, size=SIZE) as frames:
        assert next(iter(frames)).camera == CAMERA
    view = relief_client.open_view(CAMERA)
    assert relief_client.update_view(view.view_id, interactive=True).interactive

    camera = relief_client.camera()
    with pytest.raises(relief.PermissionDenied, match="control token") as caught:
        relief_client.set_camera(CAMERA)
    assert caught.value.code == "PERMISSION_DENIED" and caught.value.method == "SetCamera"
    with pytest.raises(relief.PermissionDenied):
        relief_client.reload()
    with pytest.raises(relief.PermissionDenied):
        relief_client.navigate(relief.Orbit(heading_deg=10.0))
    assert relief_client.camera() == camera, "a refused call moved the camera"


def test_a_control_token_steers(reliefd: Reliefd, tokens: TokenFile) -> None:
    with reliefd.connect(token=tokens.control) as client:
        assert client.set_camera(CAMERA).lon_deg == pytest.approx(CAMERA.lon_deg)
        generation = client.state().generation
        assert client.reload(["dem"]).generation >= generation


def test_the_token_comes_from_relief_token(
    reliefd: Reliefd, tokens: TokenFile, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RELIEF_TOKEN", tokens.control + "\n")
    with relief.connect(reliefd.address) as client:
        assert client.set_camera(CAMERA).lat_deg == pytest.approx(CAMERA.lat_deg)
    # "" sends none, whatever the environment says.
    with relief.connect(reliefd.address, token="") as client, pytest.raises(relief.Unauthenticated):
        client.state()


def test_the_asyncio_client_sends_the_token(reliefd: Reliefd, tokens: TokenFile) -> None:
    async def main() -> None:
        async with relief.aio.connect(reliefd.address, token=tokens.read) as client:
            assert (await client.state()).name == "hill"
            async with client.events() as events:
                assert isinstance(await events.__anext__(), relief.SnapshotEvent)
            with pytest.raises(relief.PermissionDenied, match="control token"):
                await client.set_camera(CAMERA)
        async with relief.aio.connect(reliefd.address, token=tokens.control) as client:
            assert (await client.set_camera(CAMERA)).lon_deg == pytest.approx(CAMERA.lon_deg)
        async with relief.aio.connect(reliefd.address, token="") as client:
            with pytest.raises(relief.Unauthenticated):
                await client.state()
            async with client.events() as events:
                with pytest.raises(relief.Unauthenticated):
                    await events.__anext__()

    asyncio.run(main())


# ------------------------------------------------------------ TLS


def test_tls_with_the_ca_is_served(secure: tuple[Reliefd, TokenFile, Certificates]) -> None:
    daemon, tokens, certs = secure
    port = daemon.address.rsplit(":", 1)[1]
    # The CA as a path, as bytes, and with an https:// or a bare address.
    for address, ca in (
        (f"https://127.0.0.1:{port}", certs.ca),
        (f"https://localhost:{port}", certs.ca.read_bytes()),
        (f"127.0.0.1:{port}", str(certs.ca)),
    ):
        with relief.connect(address, token=tokens.read, ca=ca, connect_timeout=10) as client:
            assert client.state().name == "hill", address
            assert client.endpoint.tls and repr(client).startswith("relief.Client('https://")
            with client.events() as events:
                assert isinstance(next(iter(events)), relief.SnapshotEvent)
    with daemon.connect(token=tokens.control, ca=certs.ca) as client:
        assert client.set_camera(CAMERA).lon_deg == pytest.approx(CAMERA.lon_deg)
    with daemon.connect(ca=certs.ca) as client, pytest.raises(relief.Unauthenticated):
        client.state()


def test_tls_from_relief_ca_and_relief_token(
    secure: tuple[Reliefd, TokenFile, Certificates], monkeypatch: pytest.MonkeyPatch
) -> None:
    daemon, tokens, certs = secure
    monkeypatch.setenv("RELIEF_CA", str(certs.ca))
    monkeypatch.setenv("RELIEF_TOKEN", tokens.read)
    monkeypatch.setenv("RELIEF_SERVER", daemon.address)
    with relief.connect() as client:
        assert client.endpoint.tls and client.state().name == "hill"

    async def main() -> None:
        async with relief.aio.connect() as client:
            assert client.endpoint.tls and (await client.state()).name == "hill"
            with pytest.raises(relief.PermissionDenied):
                await client.reload()

    asyncio.run(main())


def test_tls_refuses_plaintext_and_a_stranger_ca(secure: tuple[Reliefd, TokenFile, Certificates], tmp_path: Path) -> None:
    daemon, tokens, _ = secure
    with pytest.raises(relief.Unavailable, match=daemon.address):
        relief.connect(daemon.address, token=tokens.read, tls=False, connect_timeout=2)
    stranger = make_certificates(tmp_path / "other")
    with pytest.raises(relief.Unavailable, match="over TLS") as caught:
        relief.connect(daemon.address, token=tokens.read, ca=stranger.ca, connect_timeout=2)
    assert "signed by the CA given" in str(caught.value)


# ------------------------------------------------------------ reading the settings


def test_addresses_cas_and_tokens_are_read_before_any_call(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RELIEF_CA", raising=False)
    monkeypatch.delenv("RELIEF_TOKEN", raising=False)
    plain = _channel.endpoint("http://127.0.0.1:1/")
    assert (plain.target, plain.tls, plain.root_certificates, plain.token) == ("127.0.0.1:1", False, None, None)
    assert _channel.endpoint("HTTPS://reliefd.example:443", tls=True).tls
    assert _channel.endpoint("reliefd.example:443", tls=True).root_certificates is None

    pem = b"-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n"
    ca = tmp_path / "ca.pem"
    ca.write_bytes(pem)
    assert _channel.endpoint("h:1", ca=ca).root_certificates == pem
    assert _channel.endpoint("h:1", ca=pem).tls
    monkeypatch.setenv("RELIEF_CA", str(ca))
    assert _channel.endpoint("h:1").tls, "RELIEF_CA means TLS"
    assert not _channel.endpoint("h:1", tls=False).tls, "tls=False does not read RELIEF_CA"
    assert not _channel.endpoint("http://h:1").tls, "http:// does not read RELIEF_CA"

    with pytest.raises(ValueError, match="use https://"):
        _channel.endpoint("http://h:1", ca=ca)
    with pytest.raises(ValueError, match="says TLS"):
        _channel.endpoint("https://h:1", tls=False)
    with pytest.raises(ValueError, match=f"cannot read the CA certificate: .*{tmp_path / 'nope.pem'}"):
        relief.Client("h:1", ca=tmp_path / "nope.pem")
    not_pem = tmp_path / "key.txt"
    not_pem.write_text("hello")
    with pytest.raises(ValueError, match="holds no PEM certificate"):
        relief.aio.connect("h:1", ca=not_pem)
    with pytest.raises(ValueError, match="no path"):
        _channel.endpoint("https://h:1/api")

    secret = "control-0123456789abcdef"
    with_token = _channel.endpoint("h:1", token=f"  {secret}\n", tls=False, insecure=True)
    assert with_token.token == secret and secret not in repr(with_token)
    with pytest.raises(ValueError, match="white space"):
        _channel.endpoint("h:1", token="two words", tls=False, insecure=True)
    # A token goes in plaintext only to this machine, or when told.
    with pytest.raises(ValueError, match="refusing to send the token over plaintext to h:1"):
        _channel.endpoint("h:1", token=secret, tls=False)
    with pytest.raises(ValueError, match="refusing to send the token"):
        relief.Client("http://10.1.2.3:50051", token=secret)
    for here in ("127.0.0.1:1", "localhost:1", "[::1]:1", "127.0.8.9:1"):
        assert _channel.endpoint(here, token=secret).token == secret, here
    assert _channel.endpoint("h:1", token=secret, tls=True).token == secret
    monkeypatch.setenv("RELIEF_TOKEN", secret)
    assert _channel.endpoint("h:1", tls=False, insecure=True).token == secret
    assert _channel.endpoint("h:1", token="", tls=False).token is None
    assert os.environ["RELIEF_TOKEN"] == secret

