"""The recorder's fast message writer writes the bytes mcap's own ``Writer.add_message`` writes."""

from __future__ import annotations

import io
import random

from mcap.reader import make_reader
from mcap.writer import Writer

from gaitscope.sessions.formats._mcap_fast import message_adder


def _file(fast: bool, messages: list[tuple[int, int, bytes]], chunk_size: int) -> bytes:
    out = io.BytesIO()
    w = Writer(out, chunk_size=chunk_size)
    w.start(profile="", library="test")
    schema_id = w.register_schema(name="s", encoding="jsonschema", data=b"{}")
    channels = [w.register_channel(topic=f"/c{k}", message_encoding="json", schema_id=schema_id) for k in range(3)]
    add = message_adder(w)
    for channel, log_time, data in messages:
        if fast:
            add(channels[channel], log_time, data)
        else:
            w.add_message(channel_id=channels[channel], log_time=log_time, data=data, publish_time=log_time)
    w.finish()
    return out.getvalue()


def test_same_bytes_as_add_message_across_chunks_and_out_of_order_times() -> None:
    rng = random.Random(7)
    messages = []
    for k in range(3000):
        log_time = 1_700_000_000_000_000_000 + k * 5_000_000 + rng.randint(-20_000_000, 20_000_000)
        data = b'{"k":%d,"pad":"%s"}' % (k, b"x" * rng.randint(0, 300))
        messages.append((rng.randrange(3), log_time, data))
    for chunk_size in (1024, 64 * 1024, 1 << 20):  # many chunks, a few, one
        slow, fast = _file(False, messages, chunk_size), _file(True, messages, chunk_size)
        assert fast == slow
    read = make_reader(io.BytesIO(fast)).iter_messages(log_time_order=False)
    assert [(m.log_time, m.publish_time, m.data) for _, _, m in read] == [(t, t, d) for _, t, d in messages]


def test_falls_back_to_the_public_method_when_the_writer_is_not_the_expected_shape() -> None:
    calls = []

    class Other:
        def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int) -> None:
            calls.append((channel_id, log_time, data, publish_time))

    add = message_adder(Other())  # type: ignore[arg-type]
    add(3, 42, b"{}")
    assert calls == [(3, 42, b"{}", 42)]
