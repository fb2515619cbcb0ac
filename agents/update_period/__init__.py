"""Seed 001: the maximum allowable update period of quasi-decentralized networked control."""
