# One image for every HAMnet service: `docker run --network host hamnet <command> ...`,
# or a whole stack with compose/docker-compose.yml.
FROM python:3.11-slim

# open3d (perception) needs libusb at import time.
RUN apt-get update \
    && apt-get install -y --no-install-recommends libusb-1.0-0 \
    && rm -rf /var/lib/apt/lists/*

# torch first and pinned: the largest layer stays cached while the sources change.
RUN pip install --no-cache-dir torch==2.13.0

WORKDIR /app
COPY pyproject.toml README.md ./
COPY services services
COPY proto proto
RUN pip install --no-cache-dir .

ENTRYPOINT ["hamnet"]
CMD ["--help"]
