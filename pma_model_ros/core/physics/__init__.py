"""The muscle: geometry, the force models, hysteresis, flags, identified muscles and joints."""
