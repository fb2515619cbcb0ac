# Image for the node services of compose.yaml: the wncs package and its scenarios.
FROM python:3.11-slim
WORKDIR /app
COPY pyproject.toml README.md ./
COPY agents agents
COPY bus_schemas bus_schemas
COPY controllers controllers
COPY gateway gateway
COPY plants plants
COPY runtime runtime
COPY scenarios scenarios
RUN pip install --no-cache-dir .
ENTRYPOINT []
