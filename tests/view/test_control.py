"""Who may watch and who may steer (the key, the Origin, the Host, one controller, a flood), and
in headless Chromium no motion without a fresh action (a frozen tab: the browser under SIGSTOP)."""

from __future__ import annotations

import contextlib
import json
import urllib.error
import urllib.request

import pytest
import websocket
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.keys import Keys

from limbctl.view import Board, Live, PanTilt, Scene, TeleopStatus, ViewServer
from limbctl.view.control import FORWARD_PERIOD_S, Access, ControlDesk, control_request, is_loopback
from tests.safety.support import Gathered
from tests.safety.support import wait_for as wait_until
from tests.view.browser import LIMITS, chromium, drag_on_plane, frozen, text_of, wait_for

#: Longest wait (s) for a message in these tests.
WAIT_S = 10.0


class Sink(Gathered):
    """Where the controller's text goes (the page source's ``feed`` in a session)."""

    def wait_for(self, text: str) -> None:
        assert self.waits(lambda: text in self.items, WAIT_S), self.items[-5:]


@contextlib.contextmanager
def served(host: str = "127.0.0.1", **server_options):
    """A served teleop board with a sink as its source: ``(board, server, sink, holder)``."""
    board = Board()
    board.publish_scene(Scene(limits=LIMITS))
    board.publish_live(Live(mode="teleop"))
    sink = Sink()
    with ViewServer(board, host=host, port=0, **server_options) as server:
        detach, holder = server.desk.attach(sink)
        try:
            yield board, server, sink, holder
        finally:
            detach()


def open_socket(server: ViewServer, key: str | None, origin: str | None = "same"):
    """A WebSocket as a browser opens it (Origin: the page's own unless told otherwise)."""
    url = server.control_url.split("?")[0].replace("http://", "ws://") + "ws"
    url = url if key is None else f"{url}?key={key}"
    origin = server.control_url.split("/?")[0] if origin == "same" else origin
    options = {"origin": origin} if origin is not None else {"suppress_origin": True}
    return websocket.create_connection(url, timeout=WAIT_S, **options)


def control_message(client: websocket.WebSocket) -> dict:
    """The next control message (scene and live pushes in between are skipped)."""
    while True:
        message = json.loads(client.recv())
        if message["kind"] == "control":
            return message


def refused_status(call) -> int:
    with pytest.raises(websocket.WebSocketBadStatusException) as refused:
        call()
    return refused.value.status_code


def test_the_key_the_origin_and_the_host_decide_who_steers_and_one_steers_at_a_time():
    with served() as (_, server, sink, holder):
        secret = server.access.secret
        # another site's page is refused even with the key
        for forged in ("http://evil.example", "http://127.0.0.1:1", "null"):
            assert refused_status(lambda o=forged: open_socket(server, secret, origin=o)) == 403
            assert refused_status(lambda o=forged: open_socket(server, None, origin=o)) == 403
        # a program without an Origin may watch 127.0.0.1, but steering needs the page
        assert refused_status(lambda: open_socket(server, secret, origin=None)) == 403
        with contextlib.closing(open_socket(server, None, origin=None)) as watcher:
            assert control_message(watcher)["steer"] is False
        # DNS rebinding: a name that is not this machine's, pointed at 127.0.0.1
        port = server.control_url.split(":")[2].split("/")[0]
        request = urllib.request.Request(server.url, headers={"Host": f"evil.example:{port}"})
        with pytest.raises(urllib.error.HTTPError) as rebound:
            urllib.request.urlopen(request, timeout=WAIT_S)
        assert rebound.value.code == 403
        assert sink.items == []
        # the key is needed to steer, and only the right one
        assert len(secret) >= 22 and f"?key={secret}" in server.control_url
        assert "key" not in server.url  # watching 127.0.0.1 stays open
        # no key: the page watches; what it sends never reaches the source
        with contextlib.closing(open_socket(server, None)) as watcher:
            told = control_message(watcher)
            assert told["steer"] is False and "steering needs the key" in told["told"]
            watcher.send(json.dumps({"pan": 1.0, "tilt": 2.0}))
            wait_until(
                lambda: server.desk.ignored == 1, WAIT_S, "the watcher's line was not ignored"
            )
        # a wrong key, or the right one in another case: refused outright
        assert refused_status(lambda: open_socket(server, "not-the-key")) == 403
        assert refused_status(lambda: open_socket(server, secret.swapcase())) == 403
        with pytest.raises(urllib.error.HTTPError) as page:
            urllib.request.urlopen(server.url + "?key=wrong", timeout=WAIT_S)
        assert page.value.code == 403 and "wrong key" in page.value.read().decode()
        # the key: this page steers, and its lines reach the source
        with contextlib.closing(open_socket(server, secret)) as steering:
            told = control_message(steering)
            assert told["steer"] is True and "you steer the limb" in told["told"]
            assert "127.0.0.1" in holder()
            steering.send(json.dumps({"pan": 3.0, "tilt": 4.0}))
            sink.wait_for('{"pan": 3.0, "tilt": 4.0}')
        assert sink.items == ['{"pan": 3.0, "tilt": 4.0}'], "only the keyed page's line"
        assert server.desk.ignored == 1
        # one controller at a time, and the second is told who
        wait_until(lambda: holder().startswith("nobody"), WAIT_S, "the closed page kept control")
        with contextlib.closing(open_socket(server, secret)) as first:
            assert control_message(first)["steer"] is True
            with contextlib.closing(open_socket(server, secret)) as second:
                told = control_message(second)
                assert told["steer"] is False
                assert told["told"].startswith("refused: the page at 127.0.0.1:")
                assert "steers; let go there" in told["told"] and "take control" in told["told"]
                second.send(json.dumps({"pan": 9.0, "tilt": 9.0}))
                first.send(json.dumps({"pan": 1.0, "tilt": 1.0}))
                sink.wait_for('{"pan": 1.0, "tilt": 1.0}')
                assert '{"pan": 9.0, "tilt": 9.0}' not in sink.items
                first.close()
                # the first page went: the second is told the slot is free, and how to take it
                told = control_message(second)
                assert told["steer"] is False and 'click "take control"' in told["told"]


def test_a_flood_reaches_the_source_as_its_newest_message_at_a_bounded_rate():
    with served() as (_, server, sink, holder):
        with contextlib.closing(open_socket(server, server.access.secret)) as flooder:
            assert control_message(flooder)["steer"] is True
            sent = 10_000
            for i in range(sent):
                flooder.send(json.dumps({"pan": (i % 90) * 0.5, "tilt": 1.0}))
            flooder.send('{"pan": 7.25, "tilt": 7.25}')
            sink.wait_for('{"pan": 7.25, "tilt": 7.25}')
        desk = server.desk
        assert desk.forwarded == len(sink.items)
        assert desk.forwarded + desk.superseded == sent + 1
        assert sink.items[-1] == '{"pan": 7.25, "tilt": 7.25}'  # the newest wins
        # at most one message per forward period reached the source
        assert desk.forwarded < sent / 10, (desk.forwarded, FORWARD_PERIOD_S)


def test_beyond_this_machine_watching_needs_a_key_and_only_the_steering_key_steers():
    with served(host="0.0.0.0") as (_, server, sink, holder):
        access = server.access
        assert access.watch_needs_key and f"watch={access.watch_secret}" in server.url
        assert access.secret not in server.url  # the people watching cannot steer
        plain = server.url.split("?")[0].replace("0.0.0.0", "127.0.0.1")
        for path in ("", "state.json"):
            with pytest.raises(urllib.error.HTTPError) as refused:
                urllib.request.urlopen(plain + path, timeout=WAIT_S)
            assert refused.value.code == 403 and "watch=" in refused.value.read().decode()
        for query in (f"?watch={access.watch_secret}", f"?key={access.secret}"):
            assert b"<canvas" in urllib.request.urlopen(plain + query, timeout=WAIT_S).read()
        url, origin = plain.replace("http://", "ws://") + "ws", plain.rstrip("/")
        for refused_url in (url, url + "?watch=wrong"):
            with pytest.raises(websocket.WebSocketBadStatusException):
                websocket.create_connection(refused_url, timeout=WAIT_S, origin=origin)
        watched = f"{url}?watch={access.watch_secret}"
        with contextlib.closing(websocket.create_connection(watched, origin=origin)) as watcher:
            assert control_message(watcher)["steer"] is False
            keyed = f"{url}?key={access.secret}"
            with contextlib.closing(websocket.create_connection(keyed, origin=origin)) as steers:
                assert control_message(steers)["steer"] is True


def test_access_the_desk_and_control_requests_as_values():
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    local, wide = Access.for_host("127.0.0.1"), Access.for_host("0.0.0.0")
    assert not local.watch_needs_key and wide.watch_needs_key
    assert local.secret != Access.for_host("127.0.0.1").secret  # a new one per session
    assert local.key_ok(local.secret) and not local.key_ok(None) and not local.key_ok("")
    desk = ControlDesk()
    page = object()
    assert desk.claim(page, "the page at here") and not desk.forward(page, "x")  # no source
    assert desk.told(page, keyed=True)[1].endswith("takes no commands from the page")
    # only a reload of the holding tab takes control over, and clicks are read apart
    desk = ControlDesk()
    old, reloaded, other = object(), object(), object()
    assert desk.claim(old, "tab K7, opened 19:02:13", "tab-one")
    assert not desk.claim(reloaded, "tab K7, opened 19:02:13", "tab-one")  # not a reload
    assert not desk.claim(other, "tab B2, opened 19:05:00", "tab-two", reload=True)
    assert not desk.claim(other, "a program", "", reload=True)  # no tab: nothing to match
    assert desk.claim(reloaded, "tab K7, opened 19:02:13", "tab-one", reload=True)
    desk.release(old)  # the old connection closing later frees nothing
    assert desk.told(other, keyed=True)[1].startswith("refused: tab K7, opened 19:02:13 steers")
    assert control_request('{"control":"take"}') == "take"
    assert control_request('{"control": "release"}') == "release"
    assert control_request('{"control":"steal"}') is None
    assert control_request('{"control":') is None
    assert control_request('{"pan": 1, "tilt": 2}') is None


# -- no motion without a fresh action, on the page --------------------------------------------

#: The server's heartbeat in these tests (s): a stopped browser is dropped within two.
HEARTBEAT_S = 0.5
#: Live frames (each >= the 0.1 s push period) the page shows while checked to send nothing:
#: a second of the page's 20 Hz resends.
QUIET_FRAMES = 10


def publish(board: Board, written, outcome: str = "held", cycle: int = 1, **status) -> None:
    """A teleop state whose gate wrote ``written`` (pan, tilt deg) with ``outcome``; ``status``:
    its ``commanded`` (pan, tilt deg), ``words`` and ``blocked`` (as :class:`TeleopStatus`)."""
    pose, commanded = PanTilt(*written), status.pop("commanded", None)
    status = TeleopStatus(commanded and PanTilt(*commanded), pose, outcome, 200.0, cycle, **status)
    board.publish_live(Live(mode="teleop", pose=pose, teleop=status))


def show(page, board: Board, written, cycle: int, outcome: str = "held", **kw) -> None:
    """Publish one state (as :func:`publish`) and wait until the page shows its cycle."""
    publish(board, written, outcome, cycle, **kw)
    wait_for(page, lambda d: text_of(d, "cycles") == str(cycle), f"cycle {cycle} not shown")


def show_frames(page, board: Board, written, first_cycle: int, count: int = QUIET_FRAMES) -> int:
    """Show ``count`` states one by one; returns the next cycle."""
    for cycle in range(first_cycle, first_cycle + count):
        show(page, board, written, cycle)
    return first_cycle + count


def steering(page) -> bool:
    return "you steer the limb" in text_of(page, "control")


def open_steering(page, server) -> None:
    page.get(server.control_url)
    wait_for(page, steering, "the opened page does not steer")


def press(page, key, sink, sent: str) -> None:
    """Press an arrow ``key`` and wait until the line ``sent`` reaches the source."""
    ActionChains(page).send_keys(key).perform()
    sink.wait_for(sent)


def test_the_keyed_page_steers_by_click_and_arrow_keys_and_resends_its_point(browser):
    """Keys step from the written pose once the gate stopped the point; a click sets it; a tab
    paused past the loop's silence drops its point; a key pushing up a slanted edge is told as
    up alone (the server's words as they are on a watching page)."""
    page = browser
    with served() as (board, server, sink, holder):
        publish(board, (5.0, 5.0), "passed")
        open_steering(page, server)
        # Left turns the limb to +pan, as in the terminal (seen from behind the limb)
        press(page, Keys.ARROW_LEFT, sink, '{"pan":6,"tilt":5}')
        # the gate stops that point and slides the written pose: the opposite key steps from there
        show(page, board, (5.5, 4.7), 2, "corrected", commanded=(6.0, 5.0))
        press(page, Keys.ARROW_RIGHT, sink, '{"pan":4.5,"tilt":4.7}')
        # inside again (the gate passed it): keys step from the point as before
        show(page, board, (4.5, 4.7), 3, "passed", commanded=(4.5, 4.7))
        press(page, Keys.ARROW_DOWN, sink, '{"pan":4.5,"tilt":3.7}')

        # a click sets the point where it lands (to the canvas's pixel: within half a degree)
        drag_on_plane(page, [(-30.0, 20.0)])
        ActionChains(page).release().perform()
        assert sink.waits(
            lambda: any(abs(json.loads(t)["pan"] + 30.0) < 0.5 for t in sink.items), WAIT_S
        ), "the click's point never reached the source"
        last = json.loads(sink.items[-1])
        assert last["pan"] == pytest.approx(-30.0, abs=0.5)
        assert last["tilt"] == pytest.approx(20.0, abs=0.5)
        # the page resends its point while it steers (the loop holds when it stops)
        count = len(sink.items)
        assert sink.waits(lambda: len(sink.items) >= count + 5, WAIT_S)
        assert json.loads(sink.items[-1]) == last, "the resent point is not the click's"

        # frozen shorter than the heartbeat: it still steers on waking, but its point is gone
        with frozen(page):
            # lines sent before the stop landed may be on their way: 0.25 s without one (the
            # tab resends 20 times a second) means it has landed
            with sink.changed:
                while True:
                    sent = len(sink.items)
                    if not sink.changed.wait_for(lambda n=sent: len(sink.items) > n, 0.25):
                        break
            # silent for 1.5 s, three times the loop's 0.5 s silence
            assert not sink.waits(lambda: len(sink.items) > sent, 1.5)
        show_frames(page, board, (5.0, 6.0), 4)
        assert sink.items[sent:] == [], "the woken tab resent its old point"
        told = text_of(page, "control")
        assert "you steer the limb" in told and "its point was dropped" in told, told
        press(page, Keys.ARROW_LEFT, sink, '{"pan":6,"tilt":6}')  # from the written pose

        # the server names every way the point lies beyond the written pose; the page names as
        # blocked only the way its key pushes, as the terminal does, and the slide as told
        press(page, Keys.ARROW_UP, sink, '{"pan":6,"tilt":7}')
        words = "at the edge: left and up are blocked, sliding right along it"
        edge = {"commanded": (5.0, 6.0), "words": words, "blocked": ("+pan", "+tilt")}
        show(page, board, (4.4, 5.5), 14, "corrected", **edge)
        assert text_of(page, "words") == "at the edge: up is blocked, sliding right along it"
        assert text_of(page, "holds") == "the upper edge"
        page.get(server.url)  # a page that watches: the server's words as they are
        wait_for(page, lambda d: text_of(d, "cycles") == "14", "the watching page shows nothing")
        assert text_of(page, "words") == words
        assert text_of(page, "holds") == "the left and upper edge"


def test_a_tab_that_lost_control_comes_back_watching_and_steers_again_only_on_a_click(browser):
    page = browser
    with served(heartbeat_s=HEARTBEAT_S) as (board, server, sink, holder):
        publish(board, (5.0, 5.0))
        open_steering(page, server)
        press(page, Keys.ARROW_UP, sink, '{"pan":5,"tilt":6}')

        # the tab freezes; the server drops it; another page steers to (-20, 0) and leaves
        with frozen(page):
            wait_until(
                lambda: holder().startswith("nobody"), WAIT_S, "the frozen tab was not dropped"
            )
            with contextlib.closing(open_socket(server, server.access.secret)) as other:
                assert control_message(other)["steer"] is True
                other.send(json.dumps({"pan": -20.0, "tilt": 0.0}))
                sink.wait_for('{"pan": -20.0, "tilt": 0.0}')
            wait_until(lambda: holder().startswith("nobody"), WAIT_S, "the other page kept control")
            publish(board, (-20.0, 0.0), cycle=2)
            sent = len(sink.items)

        # it wakes, reconnects by itself, and sends nothing: nobody touched anything
        wait_for(page, lambda d: text_of(d, "cycles") == "2", "the woken tab never reconnected")
        cycle = show_frames(page, board, (-20.0, 0.0), 3)
        assert sink.items[sent:] == [], "the woken tab moved the limb by itself"
        assert holder().startswith("nobody")
        told = text_of(page, "control")
        assert "lost control when its connection dropped" in told, told
        assert 'click "take control"' in told, told
        assert page.find_element("id", "take").is_displayed()

        # a click takes control; the point waits for a fresh key, from the written pose
        page.find_element("id", "take").click()
        wait_for(page, steering, "the click did not take control")
        show_frames(page, board, (-20.0, 0.0), cycle)
        assert sink.items[sent:] == [], "taking control alone moved the limb"
        press(page, Keys.ARROW_UP, sink, '{"pan":-20,"tilt":1}')
        assert set(sink.items[sent:]) == {'{"pan":-20,"tilt":1}'}  # that point, resent


def test_a_reload_keeps_control_and_another_tab_is_told_which_tab_steers():
    with served() as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0))
        open_steering(page, server)
        reloads = 10
        kept = 0
        for _ in range(reloads):
            page.refresh()
            wait_for(page, lambda d: text_of(d, "control") not in ("-", ""), "no control message")
            kept += steering(page)
        assert kept == reloads, f"control kept over {kept} of {reloads} reloads"
        # the tab names itself, and a reload kept its name
        name = page.execute_script("return window.limbview.tab.name;")
        assert text_of(page, "tab-name") == f"this is {name}"
        assert page.title == f"limbctl: {name} steers"
        assert name in holder()

        # another tab opened from this one (inheriting its sessionStorage, as a duplicated tab
        # does): a name of its own; refused, told the steering tab by its name
        first = page.current_window_handle
        page.execute_script("window.open(arguments[0]);", server.control_url)
        wait_for(page, lambda d: len(d.window_handles) == 2, "no second tab")
        page.switch_to.window([h for h in page.window_handles if h != first][0])
        wait_for(page, lambda d: "refused" in text_of(d, "control"), "the second tab not refused")
        told = text_of(page, "control")
        assert name in told and 'click "take control"' in told, told
        assert page.execute_script("return window.limbview.tab.name;") != name
        assert page.find_element("id", "take").is_displayed()
        # the steering tab lets go; the other takes control with a click
        page.switch_to.window(first)
        page.find_element("id", "let-go").click()
        wait_for(page, lambda d: "you let go" in text_of(d, "control"), "let go not told")
        wait_until(lambda: holder().startswith("nobody"), WAIT_S, "letting go kept control")
        page.switch_to.window(page.window_handles[-1])
        page.find_element("id", "take").click()
        wait_for(page, steering, "the second tab's click did not take control")
        assert holder() not in ("", name) and holder().startswith("tab ")
