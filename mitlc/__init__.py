"""mitlc: compile MITL control specifications into reward Petri nets for RL."""

__version__ = "0.1.0"
