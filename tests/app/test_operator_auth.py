"""The operator station beyond loopback: users with hashed passwords, a login on every route,
roles (an operator cannot run the engineer's health check), the login recorded as the
operator — over HTTP and in the browser; and the CLI refusing another address without users."""

from __future__ import annotations

import base64
import json
import os
import stat
import urllib.error
import urllib.request

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from playwright.sync_api import Error as PlaywrightError
from playwright.sync_api import sync_playwright

from bench.app.cli import main
from bench.app.operator.auth import Users, add_user, hash_password, verify_password
from bench.testing.operator_station import CHROMIUM, serve


@settings(max_examples=8, deadline=None)  # scrypt: tens of ms a hash
@given(st.text(min_size=1, max_size=40), st.text(min_size=1, max_size=40))
def test_a_password_checks_against_its_hash_and_no_other(password, other):
    stored = hash_password(password)
    assert password not in stored.split("$")  # the hash, never the password
    assert verify_password(password, stored)
    assert verify_password(other, stored) == (other == password)
    assert hash_password(password) != stored  # a fresh salt each time


def test_a_malformed_hash_never_logs_in():
    for stored in ("", "plain", "scrypt$1$2$3", "md5$16384$8$1$00$00", "scrypt$x$8$1$00$00",
                   "scrypt$16384$8$1$zz$00"):
        assert not verify_password("secret-password", stored)


def test_users_file_written_hashed_private_and_every_mistake_named(tmp_path):
    path = tmp_path / "users.toml"
    add_user(path, "ann", "operator", "ann-password")
    add_user(path, "eve.lab", "engineer", "eve-password")
    add_user(path, "ann", "engineer", "new-password")  # replaced, not duplicated
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    text = path.read_text()
    assert "password" in text and "ann-password" not in text and "new-password" not in text
    users = Users.load(path)
    assert {n: u.role for n, u in users.users.items()} == {"ann": "engineer", "eve.lab": "engineer"}
    with pytest.raises(ValueError, match="at least 8 characters"):
        add_user(path, "bob", "operator", "short")
    with pytest.raises(ValueError, match="role 'admin' not in"):
        add_user(path, "bob", "admin", "long-enough")
    with pytest.raises(ValueError, match="user name 'b b' must be"):
        add_user(path, "b b", "operator", "long-enough")
    for content, message in [
        ('[users.ann]\nrole = "operator"\npassword = "hunter22"\n', "never the password itself"),
        ('[users.ann]\nrole = "boss"\npassword = "scrypt$1"\n', "role 'boss' not in"),
        ('[users.ann]\nrole = "operator"\n', "needs exactly 'role' and 'password'"),
        ('[people.ann]\nrole = "operator"\n', "one [users.<name>] table per user"),
        ("[users\n", "not valid TOML"),
    ]:
        path.write_text(content)
        with pytest.raises(ValueError, match=message.replace("[", r"\[").replace(".", r"\.")):
            Users.load(path)
    with pytest.raises(ValueError, match="not found"):
        Users.load(tmp_path / "none.toml")


def test_the_cli_serves_beyond_loopback_only_with_users_and_adds_users(tmp_path, monkeypatch, capsys):
    assert main(["station", "serve", "--host", "0.0.0.0", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "--host '0.0.0.0'" in err and "--users FILE" in err
    assert main(["station", "serve", "--users", str(tmp_path / "none.toml"), "--port", "0"]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["station", "serve", "--tls-cert", "c.pem", "--port", "0"]) == 2
    assert "go together" in capsys.readouterr().err
    monkeypatch.setattr("sys.stdin", __import__("io").StringIO("a-long-password\n"))
    users = tmp_path / "users.toml"
    assert main(["station", "user", str(users), "ann", "--role", "operator", "--password-stdin"]) == 0
    assert Users.load(users).authenticate(basic("ann", "a-long-password")).role == "operator"


def basic(name: str, password: str) -> str:
    return "Basic " + base64.b64encode(f"{name}:{password}".encode()).decode()


def request(url: str, auth: str | None = None, body: dict | None = None) -> tuple[int, dict, dict]:
    req = urllib.request.Request(url, data=None if body is None else json.dumps(body).encode(),
                                 headers={"Content-Type": "application/json",
                                          **({"Authorization": auth} if auth else {})})
    try:
        with urllib.request.urlopen(req) as r:
            return r.status, dict(r.headers), json.loads(r.read() or b"{}")
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), json.loads(exc.read() or b"{}")


@pytest.fixture
def users(tmp_path) -> Users:
    path = tmp_path / "users.toml"
    add_user(path, "ann", "operator", "ann-password")
    add_user(path, "eve", "engineer", "eve-password")
    return Users.load(path)


def test_every_route_needs_a_login_and_the_health_check_an_engineer(tmp_path, users):
    with serve(tmp_path, users=users) as (url, station):
        for path in ("/", "/api/state", "/api/history", "/static/station.js", "/api/whoami"):
            code, headers, _ = request(url + path)
            assert code == 401 and headers["www-authenticate"].startswith("Basic realm=")
        assert request(url + "/api/state", basic("ann", "wrong-password"))[0] == 401
        assert request(url + "/api/state", basic("mallory", "ann-password"))[0] == 401
        assert request(url + "/api/state", "Basic %%%")[0] == 401
        ann, eve = basic("ann", "ann-password"), basic("eve", "eve-password")
        assert request(url + "/api/whoami", ann)[2] == {"user": "ann", "role": "operator"}
        code, _, doc = request(url + "/api/doctor", ann)
        assert code == 403 and "for an engineer" in doc["error"]
        assert request(url + "/api/doctor", eve)[0] == 200
        # the login is the operator: an empty (or another) name in the form does not matter
        code, _, doc = request(url + "/api/start", ann, {"operator": "", "sockets": {}})
        assert code == 400 and "at least one serial" in doc["error"]
        code, _, doc = request(url + "/api/start", ann, {"operator": "someone else", "sockets": {"1": "QA-SIM-0003"}})
        assert code == 200
        code, _, doc = request(url + "/api/prompt", ann, {"answer": "abort"})  # at the mount prompt
        assert code == 200
        station.thread.join(timeout=60)
        assert station.live.operator == "ann" and station.live.state == "aborted"


def test_the_page_logs_in_and_shows_the_login_as_the_operator(tmp_path, users):
    assert CHROMIUM.exists(), f"{CHROMIUM} missing: run `make chromium` (Debian's chromium package)"
    with serve(tmp_path, users=users) as (url, _), sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox"])
        try:
            anonymous = browser.new_page()  # no login given: the browser gets no page
            with pytest.raises(PlaywrightError, match="ERR_INVALID_AUTH_CREDENTIALS"):
                anonymous.goto(url)
            wrong = browser.new_context(http_credentials={"username": "ann", "password": "not-hers"})
            response = wrong.new_page().goto(url)  # a wrong password: refused
            assert response is not None and response.status == 401
            context = browser.new_context(http_credentials={"username": "ann", "password": "ann-password"})
            page = context.new_page()
            assert page.goto(url).status == 200
            page.wait_for_function("window.stateMessages > 0")  # the event stream carries the login
            page.wait_for_function("document.getElementById('operator').value === 'ann'")
            assert page.locator("#operator").get_attribute("readonly") is not None
            page.click("#doctor-run")
            page.wait_for_selector("#doctor-table tbody tr")
            assert "for an engineer" in (page.text_content("#doctor-table") or "")
        finally:
            browser.close()

