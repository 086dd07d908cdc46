# fastcs-ethercat: the IOC, the simulator and the terminal tools in one image,
# laid out as epics-containers expects (instance config mounted at
# /epics/ioc/config, screens written to /epics/opi), running as a non-root user.
#
#   docker build -t fastcs-ethercat .                 # dependencies from PyPI
#   deploy/build-image.sh fastcs-ethercat:local       # podman, no registry needed
#   docker run --rm --network host fastcs-ethercat demo
#   docker run --rm --network host -v $PWD/config:/epics/ioc/config:ro fastcs-ethercat
#
# Dependencies come from deploy/requirements.lock, hash-checked. WHEELS=index
# (default) fetches them from the package index inside the build;
# WHEELS=context takes them from build/wheelhouse and build/app, which
# deploy/build-image.sh fills on the host first (no network inside the build).

ARG BASE_IMAGE=python:3.11-slim
ARG WHEELS=index
# The version (setuptools-scm's, from the git tag: v1.4.0 gives 1.4.0): the
# image label, and the wheel's, as the build context has no .git
# (WHEELS=index):
#   docker build --build-arg VERSION=$(python -m setuptools_scm) .
# deploy/build-image.sh passes the version of the wheel it built; CI passes
# setuptools-scm's.
ARG VERSION=0+unknown

# Wheels from the package index: the locked dependencies, hash-checked, then
# fastcs-ethercat itself from the source here (its own step, so a change of
# the source does not fetch the dependencies again).
FROM ${BASE_IMAGE} AS wheels-index
ARG VERSION
COPY deploy/requirements.lock deploy/build-pip.lock /src/deploy/
RUN python3 -m venv /opt/build \
    && /opt/build/bin/pip install --no-cache-dir --require-hashes \
        --requirement /src/deploy/build-pip.lock \
    && /opt/build/bin/pip wheel --no-cache-dir --require-hashes \
        --requirement /src/deploy/requirements.lock --wheel-dir /wheels
COPY pyproject.toml README.md LICENSE /src/
COPY src /src/src
COPY terminals /src/terminals
COPY ioc /src/ioc
RUN SETUPTOOLS_SCM_PRETEND_VERSION=${VERSION} \
    /opt/build/bin/pip wheel --no-cache-dir --no-deps --wheel-dir /wheels /src

# Wheels deploy/build-image.sh made on the host from the same lock
# (hash-checked there) and the source: no network inside the build.
FROM scratch AS wheels-context
COPY build/wheelhouse/*.whl build/app/*.whl /wheels/

# (The instruction makes this a stage of its own, which podman 4.3's
# --layers=false needs to clean up after itself.)
FROM wheels-${WHEELS} AS wheels
LABEL fastcs-ethercat.wheels="the wheels the runtime stage installs"

FROM ${BASE_IMAGE} AS runtime
ARG VERSION
# Exactly the locked set (no resolution, no network), then a non-root user
# and the epics-containers folders; /epics/ioc/terminals is the shipped
# terminal types at a path a config can name.
RUN --mount=type=bind,from=wheels,source=/wheels,target=/wheels \
    python3 -m venv /venv \
    && /venv/bin/pip install --no-cache-dir --no-index --no-deps /wheels/*.whl \
    && /venv/bin/pip check \
    && useradd --create-home --uid 1000 --user-group ioc \
    && mkdir -p /epics/ioc/config /epics/opi /epics/runtime \
    && chown ioc:ioc /epics/opi /epics/runtime \
    && shipped=$(/venv/bin/python -c \
        "import fastcs_ethercat.shipped as s; print(s.BUILTIN_TERMINALS_DIR)") \
    && ln -s "$shipped" /epics/ioc/terminals

# The probes the ioc-instance chart runs by default (livenessExecutable,
# preStopExecutable), reading the heartbeat file the IOC rewrites every second;
# the chain cache and the start count in the chart's persistent /epics/runtime.
COPY deploy/image/liveness.sh deploy/image/stop.sh /epics/ioc/
ENV PATH=/venv/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    FASTCS_ETHERCAT_IMAGE=1 \
    FASTCS_ETHERCAT_RUNTIME_DIR=/epics/runtime \
    FASTCS_ETHERCAT_HEARTBEAT_FILE=/tmp/fastcs-ethercat.heartbeat
WORKDIR /epics/ioc
USER ioc
# EPICS CA (5064/tcp+udp, repeater 5065/udp) and PVA (5075/tcp, 5076/udp).
EXPOSE 5064/tcp 5064/udp 5065/udp 5075/tcp 5076/udp
LABEL org.opencontainers.image.title="fastcs-ethercat" \
      org.opencontainers.image.version="${VERSION}" \
      org.opencontainers.image.description="EPICS IOC serving Beckhoff EtherCAT terminals under TwinCAT" \
      org.opencontainers.image.licenses="Apache-2.0"
ENTRYPOINT ["fastcs-ethercat"]
CMD ["ioc", "--config", "/epics/ioc/config/ioc.yaml"]
