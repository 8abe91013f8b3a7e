import pytest

from robot_client.protocol import (
    FRAME_HEADER,
    MAX_TEXT_BYTES,
    ProtocolError,
    decode,
    encode,
    pack_frame,
    unpack_frame,
)

JPEG = b"\xff\xd8" + b"\x00" * 100 + b"\xff\xd9"


def test_frame_round_trip_keeps_header_and_payload():
    data = pack_frame(7, 123_456_789_012, 640, 480, JPEG)
    header, jpeg = unpack_frame(data)
    assert (header.seq, header.capture_ns, header.width, header.height) == (7, 123_456_789_012, 640, 480)
    assert jpeg == JPEG
    assert len(data) == FRAME_HEADER.size + len(JPEG) == 20 + len(JPEG)


@pytest.mark.parametrize(
    "data, words",
    [
        (b"RSF1", "too short"),
        (b"XXXX" + pack_frame(1, 1, 2, 2, JPEG)[4:], "expected b'RSF1'"),
        (pack_frame(1, 1, 0, 2, JPEG), "size 0x2"),
        (pack_frame(1, 1, 2, 2, b"GIF89a..."), "not a JPEG"),
    ],
)
def test_malformed_frames_are_named(data, words):
    with pytest.raises(ProtocolError, match=words.replace("(", r"\(")):
        unpack_frame(data)


def test_oversized_frame_is_refused_before_parsing():
    with pytest.raises(ProtocolError, match="limit is 1000"):
        unpack_frame(pack_frame(1, 1, 2, 2, JPEG + b"\x00" * 1000), max_bytes=1000)


def test_text_messages_must_be_typed_json_objects():
    assert decode(encode({"type": "ping", "id": 3}), ("ping",)) == {"type": "ping", "id": 3}
    with pytest.raises(ProtocolError, match="not JSON"):
        decode("{nope")
    with pytest.raises(ProtocolError, match="'type'"):
        decode("[1, 2]")
    with pytest.raises(ProtocolError, match="unknown message type 'dance'"):
        decode('{"type": "dance"}', ("ping", "move"))
    with pytest.raises(ProtocolError, match="limit"):
        decode('{"type": "x", "pad": "' + "a" * MAX_TEXT_BYTES + '"}')
