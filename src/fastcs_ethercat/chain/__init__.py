"""The chain file: which TwinCAT system a chain describes (`chain.file`).

Below both readers: the IOC boots from one without the PLC, the simulator
plays one, `chain dump` writes one.
"""
