# Multi-stage build of the sagnac release binary.
# Stage 1: build with the official Rust toolchain image.
FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY config ./config
RUN cargo build --release --locked --bin sagnac

# Stage 2: slim runtime with only the binary and its default config.
FROM debian:bookworm-slim
RUN useradd --system --no-create-home sagnac && mkdir -p /var/lib/sagnac && chown sagnac /var/lib/sagnac
COPY --from=build /src/target/release/sagnac /usr/local/bin/sagnac
COPY --from=build /src/config /etc/sagnac
USER sagnac
WORKDIR /var/lib/sagnac
# Metrics bind loopback by default; publish with --metrics-addr 0.0.0.0:9898 inside a container.
EXPOSE 9898
ENTRYPOINT ["/usr/local/bin/sagnac"]
CMD ["run", "--config", "/etc/sagnac/default.toml", "--record-dir", "/var/lib/sagnac"]
