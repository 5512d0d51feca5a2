# The sagnac daemon in a container.
#   docker build -t sagnac .
#   docker run --rm -p 9898:9898 sagnac                      # the simulated bench
#   docker run --rm -p 9898:9898 --device /dev/ttyUSB0 --group-add dialout \
#     -v "$PWD/recordings:/var/lib/sagnac/recordings" sagnac \
#     run --config /etc/sagnac/default.toml --serial /dev/ttyUSB0 \
#         --metrics-addr 0.0.0.0:9898 --record-dir /var/lib/sagnac/recordings
# Outside a container the daemon binds 127.0.0.1:9898; inside, the default
# command binds 0.0.0.0:9898 so that `-p 9898:9898` reaches /metrics.

# Stage 1: build the release binary with the official Rust image (it has gcc
# for the zstd and lz4 C sources).
FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY config ./config
COPY assets ./assets
RUN cargo build --release --locked --bin sagnac

# Stage 2: a slim runtime with the binary, its config files and curl for the
# health check.
FROM debian:bookworm-slim
RUN apt-get update \
    && apt-get install -y --no-install-recommends curl \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --no-create-home --home-dir /var/lib/sagnac sagnac \
    && mkdir -p /var/lib/sagnac/recordings \
    && chown -R sagnac /var/lib/sagnac
COPY --from=build /src/target/release/sagnac /usr/local/bin/sagnac
COPY --from=build /src/config /etc/sagnac
USER sagnac
WORKDIR /var/lib/sagnac
EXPOSE 9898
# Healthy while /metrics answers 200 on the default command's port.
HEALTHCHECK --interval=30s --timeout=5s --start-period=15s --retries=3 \
    CMD ["curl", "-fsS", "-o", "/dev/null", "http://127.0.0.1:9898/metrics"]
ENTRYPOINT ["/usr/local/bin/sagnac"]
CMD ["run", "--config", "/etc/sagnac/default.toml", "--metrics-addr", "0.0.0.0:9898", "--record-dir", "/var/lib/sagnac/recordings"]
