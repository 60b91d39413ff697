"""renderloop: a render-in-the-loop aerial robotics simulator and its sweet-pepper yield estimation."""

__version__ = "0.1.0"
