"""No motion without a fresh action, on the page: a tab that lost control comes back watching and
steers again only on a click; a reload keeps control; the tab that steers is named as it names
itself; the arrow keys step from the written pose once the gate stopped the point short, and
turn the limb the way the terminal's keys do (seen from behind it).

Real headless Chromium against the real server; a frozen tab is the browser stopped with
SIGSTOP, dropped by the server's own heartbeat (shortened here so the test waits seconds, not
tens of them).
"""

from __future__ import annotations

import contextlib
import json

from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.keys import Keys

from limbctl.view import HardLimits, Live, PanTilt, Scene, TeleopStatus, ViewServer
from limbctl.view.state import Board
from tests.view.browser import chromium, frozen, text_of, wait_for
from tests.view.test_control import Sink, control_message, open_socket, wait_until

#: The server's heartbeat in these tests (s): a stopped browser is dropped within two.
HEARTBEAT_S = 0.5
#: Live frames the page must show, one after another, while it is checked to send nothing: each
#: takes at least the server's 0.1 s push period, so ten span a second of the page's 20 Hz
#: resends (twenty chances to send an old point).
QUIET_FRAMES = 10


@contextlib.contextmanager
def steered_board(heartbeat_s: float = HEARTBEAT_S):
    """A served teleop board with a sink attached: ``(board, server, sink, holder)``."""
    board = Board()
    board.publish_scene(Scene(limits=HardLimits((-90.0, 90.0), (-40.0, 60.0))))
    sink = Sink()
    with ViewServer(board, port=0, heartbeat_s=heartbeat_s) as server:
        detach, holder = server.desk.attach(sink)
        try:
            yield board, server, sink, holder
        finally:
            detach()


def publish(
    board: Board,
    written,
    outcome: str = "held",
    cycle: int = 1,
    commanded=None,
    words: str = "",
    blocked: tuple[str, ...] = (),
) -> None:
    """A teleop state whose gate wrote ``written`` (pan, tilt deg) with ``outcome``."""
    pose = PanTilt(*written)
    commanded = PanTilt(*commanded) if commanded is not None else None
    status = TeleopStatus(commanded, pose, outcome, 200.0, cycle, words, blocked)
    board.publish_live(Live(mode="teleop", pose=pose, teleop=status))


def show_frames(page, board: Board, written, first_cycle: int, count: int = QUIET_FRAMES) -> int:
    """Publish ``count`` states one by one, each waited for on the page; the next cycle."""
    for cycle in range(first_cycle, first_cycle + count):
        publish(board, written, cycle=cycle)
        wait_for(page, lambda d, c=cycle: text_of(d, "cycles") == str(c), f"cycle {cycle}")
    return first_cycle + count


def steering(page) -> bool:
    return "you steer the limb" in text_of(page, "control")


def steer_up_once(page, server, sink) -> None:
    """Open the steering page on a limb at (5, 5) and press Up once: (5, 6) reaches the loop."""
    page.get(server.control_url)
    wait_for(page, steering, "the opened page does not steer")
    ActionChains(page).send_keys(Keys.ARROW_UP).perform()
    sink.wait_for('{"pan":5,"tilt":6}')


def test_a_tab_that_lost_control_comes_back_watching_and_steers_again_only_on_a_click():
    with steered_board() as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0))
        steer_up_once(page, server, sink)

        # the tab freezes; the server drops it; another page steers to (-20, 0) and leaves
        with frozen(page):
            wait_until(lambda: holder().startswith("nobody"), "the frozen tab was not dropped")
            with contextlib.closing(open_socket(server, server.access.secret)) as other:
                assert control_message(other)["steer"] is True
                other.send(json.dumps({"pan": -20.0, "tilt": 0.0}))
                sink.wait_for('{"pan": -20.0, "tilt": 0.0}')
            wait_until(lambda: holder().startswith("nobody"), "the other page kept control")
            publish(board, (-20.0, 0.0), cycle=2)
            sent = len(sink.lines)

        # it wakes, reconnects by itself, and sends nothing: nobody touched anything
        wait_for(page, lambda d: text_of(d, "cycles") == "2", "the woken tab never reconnected")
        cycle = show_frames(page, board, (-20.0, 0.0), 3)
        assert sink.lines[sent:] == [], "the woken tab moved the limb by itself"
        assert holder().startswith("nobody")
        told = text_of(page, "control")
        assert "lost control when its connection dropped" in told, told
        assert 'click "take control"' in told, told
        assert page.find_element("id", "take").is_displayed()

        # a click takes control; the point waits for a key (a fresh action), then starts from
        # where the limb was written, not from the old point
        page.find_element("id", "take").click()
        wait_for(page, steering, "the click did not take control")
        show_frames(page, board, (-20.0, 0.0), cycle)
        assert sink.lines[sent:] == [], "taking control alone moved the limb"
        ActionChains(page).send_keys(Keys.ARROW_UP).perform()
        sink.wait_for('{"pan":-20,"tilt":1}')
        assert set(sink.lines[sent:]) == {'{"pan":-20,"tilt":1}'}  # that point, resent


def test_a_reload_keeps_control_and_another_tab_is_told_which_tab_steers():
    with steered_board(heartbeat_s=5.0) as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0))
        page.get(server.control_url)
        wait_for(page, steering, "the opened page does not steer")
        reloads = 10
        kept = 0
        for _ in range(reloads):
            page.refresh()
            wait_for(page, lambda d: text_of(d, "control") not in ("-", ""), "no control message")
            kept += steering(page)
        print(f"control kept over {kept} of {reloads} reloads")
        assert kept == reloads
        # the tab names itself, and a reload kept its name
        name = page.execute_script("return window.limbview.tab.name;")
        assert text_of(page, "tab-name") == f"this is {name}"
        assert page.title == f"limbctl: {name} steers"
        assert name in holder()

        # another tab, opened from this one (so it inherits its sessionStorage, as a duplicated
        # tab does): a name of its own; refused, told the steering tab by the name it shows
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
        wait_until(lambda: holder().startswith("nobody"), "letting go kept control")
        page.switch_to.window(page.window_handles[-1])
        page.find_element("id", "take").click()
        wait_for(page, steering, "the second tab's click did not take control")
        assert holder() not in ("", name) and holder().startswith("tab ")


def test_arrow_keys_step_from_the_written_pose_once_the_gate_stopped_the_point():
    with steered_board(heartbeat_s=5.0) as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0), "passed")
        page.get(server.control_url)
        wait_for(page, steering, "the opened page does not steer")
        keys = ActionChains(page)
        # Left turns the limb to +pan, as in the terminal (seen from behind the limb)
        keys.send_keys(Keys.ARROW_LEFT).perform()
        sink.wait_for('{"pan":6,"tilt":5}')
        # the gate stops that point at an edge and slides the written pose (5.5, 4.7)
        publish(board, (5.5, 4.7), "corrected", cycle=2, commanded=(6.0, 5.0))
        wait_for(page, lambda d: text_of(d, "cycles") == "2", "no stopped state")
        # the first opposite key moves a full step from there, not from the point beyond it
        ActionChains(page).send_keys(Keys.ARROW_RIGHT).perform()
        sink.wait_for('{"pan":4.5,"tilt":4.7}')
        # inside again (the gate passed it): keys step from the point as before
        publish(board, (4.5, 4.7), "passed", cycle=3, commanded=(4.5, 4.7))
        wait_for(page, lambda d: text_of(d, "cycles") == "3", "no passed state")
        ActionChains(page).send_keys(Keys.ARROW_DOWN).perform()
        sink.wait_for('{"pan":4.5,"tilt":3.7}')


def test_a_key_pushing_up_against_a_slanted_edge_is_told_as_up_alone():
    """The server names every way the point lies beyond the written pose; the page names as
    blocked only the way its arrow key pushes, as the terminal does, and the slide as told."""
    with steered_board(heartbeat_s=5.0) as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0), "passed")
        steer_up_once(page, server, sink)
        # the gate slid the written pose right and a little up along a slanted edge
        words = "at the edge: left and up are blocked, sliding right along it"
        publish(board, (4.4, 5.5), "corrected", 2, (5.0, 6.0), words, ("+pan", "+tilt"))
        wait_for(page, lambda d: text_of(d, "cycles") == "2", "no stopped state")
        assert text_of(page, "words") == "at the edge: up is blocked, sliding right along it"
        assert text_of(page, "holds") == "the upper edge"
        # a page that watches (no key pushes) tells the server's words as they are
        page.get(server.url)
        wait_for(page, lambda d: text_of(d, "cycles") == "2", "the watching page shows nothing")
        assert text_of(page, "words") == words
        assert text_of(page, "holds") == "the left and upper edge"


def test_a_tab_paused_past_the_loops_silence_drops_its_point_and_keeps_control():
    """Frozen shorter than the server's heartbeat: the tab still steers when it wakes, but
    the point it had is gone; it sends nothing until a key, and says why."""
    with steered_board(heartbeat_s=5.0) as (board, server, sink, holder), chromium() as page:
        publish(board, (5.0, 5.0))
        steer_up_once(page, server, sink)
        with frozen(page):
            # lines the tab sent before the stop landed may still be on their way: let them in
            # (the tab resends its point 20 times a second; on loopback one arrives in a
            # millisecond, so 0.25 s without one means the stop has landed)
            with sink.changed:
                while True:
                    sent = len(sink.lines)
                    if not sink.changed.wait_for(lambda n=sent: len(sink.lines) > n, 0.25):
                        break
            # the frozen tab stays silent for 1.5 s, three times the loop's 0.5 s silence
            with sink.changed:
                assert not sink.changed.wait_for(lambda: len(sink.lines) > sent, 1.5)
        show_frames(page, board, (5.0, 6.0), 2)
        assert sink.lines[sent:] == [], "the woken tab resent its old point"
        told = text_of(page, "control")
        assert "you steer the limb" in told and "its point was dropped" in told, told
        ActionChains(page).send_keys(Keys.ARROW_LEFT).perform()
        sink.wait_for('{"pan":6,"tilt":6}')  # from the written pose, a fresh key
