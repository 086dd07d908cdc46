# fastcs-ethercat: the IOC, the simulator and the terminal tools in one image.
#
#   docker build -t fastcs-ethercat .
#   docker run --rm --network host fastcs-ethercat ioc --config /opt/fastcs-ethercat/ioc/demo.yaml
#
# Stage 1 builds the wheel; stage 2 installs it into a slim image and runs as a
# non-root user. tests/test_packaging.py performs the same install steps in a
# fresh venv, since CI has no Docker engine.

FROM python:3.11-slim AS build
WORKDIR /src
COPY pyproject.toml README.md ./
COPY src ./src
RUN pip install --no-cache-dir build \
    && python -m build --wheel --outdir /dist

FROM python:3.11-slim AS runtime
RUN useradd --create-home --uid 1000 ioc
COPY --from=build /dist/*.whl /tmp/
RUN python -m venv /opt/venv \
    && /opt/venv/bin/pip install --no-cache-dir /tmp/*.whl \
    && rm /tmp/*.whl
COPY terminals /opt/fastcs-ethercat/terminals
COPY ioc /opt/fastcs-ethercat/ioc
ENV PATH=/opt/venv/bin:$PATH
WORKDIR /opt/fastcs-ethercat
USER ioc
# EPICS CA (5064/5065) and PVA (5075/5076) ports the IOC serves on.
EXPOSE 5064/tcp 5064/udp 5065/udp 5075/tcp 5076/udp
ENTRYPOINT ["fastcs-ethercat"]
CMD ["--help"]
