#pragma once
// Streamed files of the services (common.proto's FileChunk / OccupancyChunk): maps and meshes
// exceed gRPC's 4 MiB message limit, so they go out in chunks of chunk_size bytes.

#include <cstdint>
#include <functional>
#include <string>

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>
#include <grpcpp/support/sync_stream.h>

#include "mav/v1/common.pb.h"

#include "mav/common/status.h"
#include "mav/dataset/occupancy_grid.h"
#include "services/common/proto_enum.h"

namespace mav::service_common {

inline constexpr uint32_t kDefaultChunkBytes = 1 << 20;
inline constexpr uint32_t kMinChunkBytes = 4096;
inline constexpr uint32_t kMaxChunkBytes = 4 << 20;

// The chunk size of a request (0 = 1 MiB); InvalidArgument "chunk_size: must be in [4096,
// 4194304] bytes, got N".
Result<uint32_t> ChunkSize(uint32_t requested);

// UNSPECIFIED means OCTOMAP_BT.
inline constexpr auto kOccupancyFormatCodec =
    MakeEnumCodec<v1::OccupancyFormat, v1::OccupancyFormat>(
        v1::OccupancyFormat_descriptor,
        {{v1::OCCUPANCY_FORMAT_OCTOMAP_BT, v1::OCCUPANCY_FORMAT_OCTOMAP_BT},
         {v1::OCCUPANCY_FORMAT_MAVOCC, v1::OCCUPANCY_FORMAT_MAVOCC}},
        v1::OCCUPANCY_FORMAT_OCTOMAP_BT);

// The format of a request (UNSPECIFIED = OCTOMAP_BT); InvalidArgument "format: unknown value N".
Result<v1::OccupancyFormat> OccupancyFormatFromProto(v1::OccupancyFormat format);

// Streams `bytes` as FileChunks of at most `chunk_bytes`; `send(chunk, first)` wraps and writes
// each one and returns false when the client went away (CANCELLED then). An empty file is one
// empty last chunk.
grpc::Status StreamChunks(grpc::ServerContext* context, const std::string& bytes,
                          uint32_t chunk_bytes,
                          const std::function<bool(v1::FileChunk&&, bool first)>& send);

// Encodes `grid` in `format` (OctoMap .bt or .mavocc) and streams it as OccupancyChunks, the
// first one carrying format, resolution and bounds.
grpc::Status StreamOccupancy(grpc::ServerContext* context, const dataset::OccupancyGrid& grid,
                             v1::OccupancyFormat format, uint32_t chunk_bytes,
                             grpc::ServerWriter<v1::OccupancyChunk>* writer);

}  // namespace mav::service_common
