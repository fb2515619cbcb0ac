"""A forged message that reaches its subscribers *before* the genuine one changes nothing
(issue 20; with counts alone it stood in for the genuine one): a node takes exactly the
messages whose digests the tick announces (``kernel.node``), so a well-formed envelope from
the key's owner, stamped with the right round and carrying a valid but different body,
neither counts as the genuine message nor is handed to a behaviour. Here the network node
itself puts the forgery on the key just before each of its genuine messages, through its own
session: zenoh keeps one session's order on a key, so every subscriber files the forgery
first, every time."""

from __future__ import annotations

from bus_schemas import codec, keys
from kernel.node import BusNode
from runtime.history import messages_digest
from runtime.launcher import launch
from tests.conftest import BENCHMARK


def test_a_forgery_filed_before_the_genuine_message_is_refused_and_counted(tmp_path, monkeypatch):
    clean = launch(BENCHMARK, tmp_path / "clean", engine="threads")
    assert clean.code == 0, clean.error
    forged: dict[str, int] = {}
    genuine_put = BusNode._put

    def forge_first(self, rel, body):
        if self.name == "network" and "value" in type(body).model_fields:
            fake = body.model_copy(update={"value": body.value + 1.0})
            payload = codec.encode(
                run=self.run_id,
                src=self.name,
                seq=self._seq,  # the genuine message's own number, round and time
                round=max(self.round, 0),
                t=self.behaviour.now,
                body=fake,
            )
            self.ctx.session.put(keys.full(self.run_id, rel), payload)
            forged[rel] = forged.get(rel, 0) + 1
        return genuine_put(self, rel, body)

    monkeypatch.setattr(BusNode, "_put", forge_first)
    res = launch(BENCHMARK, tmp_path / "forged", engine="threads")
    assert res.code == 0, res.error
    assert forged and sum(forged.values()) > 20
    # the history holds the genuine messages only, the clean run's bit for bit
    clean_history = messages_digest(tmp_path / "clean" / "history.sqlite")
    assert messages_digest(tmp_path / "forged" / "history.sqlite") == clean_history
    assert res.summary["loops"] == clean.summary["loops"]
    # every forgery was refused and counted (each subscriber of its key saw each one)
    assert res.summary["messages"]["dropped_invalid"] == forged
