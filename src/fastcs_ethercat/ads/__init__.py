"""The ADS protocol: a sans-I/O codec (bytes in, dataclasses out, and back).

The simulator encodes responses and decodes requests with these modules; the
IOC decodes the raw bytes pyads hands back with the same ones, so a layout bug
shows up as a failing round trip instead of two bugs that agree.
"""
