"""From measured force maps to identified models, judged by nested held-out error."""
