"""Helpers of the audio messages (horus/msg/audio.hmsg), mirroring the C++ mixins."""


class AudioFrameMixin:
    def valid_samples(self) -> int:
        """num_samples, capped at MAX_SAMPLES."""
        return min(self.num_samples, self.MAX_SAMPLES)

    def frame_count(self) -> int:
        """Frames (samples per channel); 0 without channels."""
        return 0 if self.channels == 0 else self.valid_samples() // self.channels

    def duration_ms(self) -> float:
        """Duration of the valid samples in milliseconds; 0 without a rate or channels."""
        if self.sample_rate == 0 or self.channels == 0:
            return 0.0
        return float(self.valid_samples()) / self.channels / self.sample_rate * 1000.0
