"""The TwinCAT simulator: the model of `twincat/` served over real ADS, and
the asyncio I/O around it.

`server` (AMS/TCP), `udp` (the UDP discovery/route port), `control` (the
HTTP control API: faults, states, values), `faults` and `counters` (what
control and the server inject and count), `notifications` (device
notifications sampled from the model), `runner` (one simulator: model, servers
and the I/O task's clock), `process` (`SimProcess`: a simulator as a child
process), `probe` (`SimProbe`: an in-process client for tests, benchmarks and
tools).
"""
