"""The simulators' physics: a muscle and a joint on the measured maps."""
