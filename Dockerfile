# Image for the services of compose.yaml: the wncs package and its scenarios, installed from the
# lock file as `make` installs them (the dev tools come along: the lock is one set).
FROM python:3.11-slim
WORKDIR /app
COPY requirements.lock pyproject.toml README.md ./
RUN pip install --no-cache-dir --require-hashes --no-deps -r requirements.lock
COPY agents agents
COPY bus_schemas bus_schemas
COPY controllers controllers
COPY core core
COPY dashboard dashboard
COPY gateway gateway
COPY kernel kernel
COPY plants plants
COPY runtime runtime
COPY cli cli
COPY scenario scenario
COPY wncs wncs
COPY scenarios scenarios
RUN pip install --no-cache-dir --no-deps --no-build-isolation .
ENTRYPOINT []
