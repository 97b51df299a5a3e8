# mlsreg server image. Multi-stage: the build stage runs the same install and build scripts as
# the README and CI; the runtime stage holds only the binary and the Debian packages owning its
# shared libraries (computed by scripts/runtime-packages.sh in the build stage).
#
#   docker build -t mlsreg .
#   docker run -p 50051:50051 -v mlsreg-data:/var/lib/mlsreg -e MLSREG_TOKEN=secret mlsreg
#
# Port 50051: gRPC (mlsreg.v1 services, grpc.health.v1; reflection only with
# MLSREG_REFLECTION=true, off by default). Port 9464: Prometheus
# /metrics (plain HTTP, no token; MLSREG_METRICS_LISTEN, empty turns it off). Volume /var/lib/mlsreg:
# persisted targets. Configuration: MLSREG_* environment variables (see `mlsreg serve --help`)
# or a JSON file via MLSREG_CONFIG.

FROM debian:12 AS build
WORKDIR /src
COPY scripts/install-deps.sh scripts/
RUN bash scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN BUILD_DIR=/build bash scripts/build.sh -DMLSREG_BUILD_TESTS=OFF -DMLSREG_BUILD_BENCHMARKS=OFF \
      -DMLSREG_BUILD_PYTHON=OFF \
 && bash scripts/runtime-packages.sh /build/mlsreg /build/libmlsreg_transport.so \
      > /build/runtime-packages.txt \
 && strip /build/mlsreg /build/libmlsreg_transport.so

FROM debian:12-slim AS runtime
COPY --from=build /build/runtime-packages.txt /tmp/runtime-packages.txt
RUN apt-get update \
 && apt-get install -y --no-install-recommends $(cat /tmp/runtime-packages.txt) ca-certificates \
 && rm -rf /var/lib/apt/lists/* /tmp/runtime-packages.txt \
 && useradd --system --uid 10001 --home-dir /var/lib/mlsreg --create-home mlsreg
COPY --from=build /build/mlsreg /usr/local/bin/mlsreg
# The gRPC client and server, which `mlsreg serve` and the client commands load (cli/transport.h).
COPY --from=build /build/libmlsreg_transport.so /usr/local/lib/mlsreg/libmlsreg_transport.so
USER mlsreg
VOLUME /var/lib/mlsreg
EXPOSE 50051 9464
# Listen on all interfaces inside the container. Plaintext off loopback needs an explicit choice:
# either TLS (MLSREG_TLS_CERT / MLSREG_TLS_KEY) or MLSREG_ALLOW_INSECURE_REMOTE=true behind a
# TLS-terminating proxy or on a private network.
ENV MLSREG_LISTEN=0.0.0.0:50051 \
    MLSREG_METRICS_LISTEN=0.0.0.0:9464 \
    MLSREG_DATA_DIR=/var/lib/mlsreg
HEALTHCHECK --interval=10s --timeout=3s --start-period=5s --retries=3 \
  CMD ["mlsreg", "health", "--server", "127.0.0.1:50051", "--attempts", "1", "--deadline", "2"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["mlsreg", "serve"]
