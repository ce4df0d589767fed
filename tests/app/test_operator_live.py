"""The operator page's live state (``LiveBatch``) as an ``Operator``: a prompt waits for the
page's answer, and an Abort pressed before the prompt came up is not lost."""

from __future__ import annotations

import threading

from bench.app.operator.live import LiveBatch


def asking(live: LiveBatch, text: str) -> tuple[threading.Thread, list[bool]]:
    answers: list[bool] = []
    thread = threading.Thread(target=lambda: answers.append(live.ask(text)), daemon=True)
    thread.start()
    return thread, answers


def wait_for_prompt(live: LiveBatch) -> dict:
    for _ in range(500):
        snap = live.snapshot()
        if snap["prompt"]:
            return snap["prompt"]
        threading.Event().wait(0.01)
    raise AssertionError("the prompt never came up")


def test_a_prompt_waits_for_continue_or_abort_from_the_page():
    live = LiveBatch()
    live.begin("Ann", "QA-2000-SIM", {1: "QA-SIM-0001"}, [("turn_on", 10.0)])
    assert live.name == "Ann" and not live.answer(True)  # no prompt open: nothing to answer
    thread, answers = asking(live, "Close the cover")
    assert wait_for_prompt(live)["text"] == "Close the cover"
    assert live.answer(True)
    thread.join(5)
    assert answers == [True] and live.snapshot()["prompt"] is None
    thread, answers = asking(live, "Close the cover")
    wait_for_prompt(live)
    live.running()
    assert live.request_abort()
    thread.join(5)
    assert answers == [False] and live.abort_requested


def test_an_abort_pressed_before_the_prompt_stands():
    live = LiveBatch()
    live.begin("Ann", "QA-2000-SIM", {1: "QA-SIM-0001"}, [("turn_on", 10.0)])
    live.running()
    assert live.request_abort()
    thread, answers = asking(live, "Close the cover")
    thread.join(5)
    assert not thread.is_alive() and answers == [False]
