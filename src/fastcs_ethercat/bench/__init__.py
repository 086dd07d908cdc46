"""Benchmarks against the protocol's limits: `fastcs-ethercat bench`.

Everything runs on loopback: the simulator and the IOC each in their own
process, the CA client in this one. Figures are printed and written as JSON,
never asserted.
"""
