"""Helpers of GenericMessage (horus/msg/generic.hmsg), mirroring the C++ mixin: dict (or any
MessagePack-able value) in and out via python3-msgpack, the 4096-byte limit checked every way
in and out with the same error text as C++ (ValueError here, horus::Error there)."""


def _msgpack():
    """msgpack, imported on first use so that importing the message package stays fast."""
    import msgpack
    return msgpack



def _check_payload_size(size: int, where: str, limit: int) -> None:
    if size > limit:
        raise ValueError(f"{where}: payload of {size} bytes exceeds the {limit}-byte maximum "
                         "of GenericMessage")


class GenericMessageMixin:
    @classmethod
    def new(cls, data: bytes):
        """A message holding the raw MessagePack bytes `data`."""
        _check_payload_size(len(data), "GenericMessage::new", cls.MAX_PAYLOAD)
        return cls(data=bytes(data))

    @classmethod
    def with_metadata(cls, data: bytes, metadata: str):
        """A message holding `data` and the metadata string `metadata`."""
        _check_payload_size(len(data), "GenericMessage::with_metadata", cls.MAX_PAYLOAD)
        return cls(data=bytes(data), metadata=metadata)

    @classmethod
    def from_value(cls, value):
        """A message holding `value` (dict, list, str, numbers, bytes ...) packed as MessagePack."""
        packed = _msgpack().packb(value, use_bin_type=True)
        _check_payload_size(len(packed), "GenericMessage::from_value", cls.MAX_PAYLOAD)
        return cls(data=packed)

    def to_value(self):
        """The payload unpacked; ValueError when too large or not one MessagePack value."""
        _check_payload_size(len(self.data), "GenericMessage::to_value", self.MAX_PAYLOAD)
        try:
            return _msgpack().unpackb(bytes(self.data), raw=False, strict_map_key=False)
        except (_msgpack().ExtraData, _msgpack().UnpackException, ValueError) as e:
            raise ValueError("GenericMessage::to_value: the payload is not a MessagePack value "
                             f"({e})") from e
