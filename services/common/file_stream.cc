#include "services/common/file_stream.h"

#include <algorithm>

#include "mav/dataset/occupancy_io.h"
#include "services/common/grpc_status.h"

namespace mav::service_common {

Result<uint32_t> ChunkSize(uint32_t requested) {
  const uint32_t bytes = requested == 0 ? kDefaultChunkBytes : requested;
  if (bytes < kMinChunkBytes || bytes > kMaxChunkBytes) {
    return Status::InvalidArgument("chunk_size: must be in [4096, 4194304] bytes, got " +
                                   std::to_string(requested));
  }
  return bytes;
}

Result<v1::OccupancyFormat> OccupancyFormatFromProto(v1::OccupancyFormat format) {
  return kOccupancyFormatCodec.FromProto(format, "format");
}

grpc::Status StreamChunks(grpc::ServerContext* context, const std::string& bytes,
                          uint32_t chunk_bytes,
                          const std::function<bool(v1::FileChunk&&, bool first)>& send) {
  const uint64_t total = bytes.size();
  uint64_t offset = 0;
  do {
    if (context->IsCancelled()) return ToGrpcStatus(Status::Cancelled("cancelled by the client"));
    const uint64_t n = std::min<uint64_t>(chunk_bytes, total - offset);
    v1::FileChunk chunk;
    chunk.set_offset(offset);
    chunk.set_total_size(total);
    chunk.set_data(bytes.substr(offset, n));
    chunk.set_last(offset + n == total);
    if (!send(std::move(chunk), offset == 0)) {
      return ToGrpcStatus(Status::Cancelled("the client went away"));
    }
    offset += n;
  } while (offset < total);
  return grpc::Status::OK;
}

grpc::Status StreamOccupancy(grpc::ServerContext* context, const dataset::OccupancyGrid& grid,
                             v1::OccupancyFormat format, uint32_t chunk_bytes,
                             grpc::ServerWriter<v1::OccupancyChunk>* writer) {
  Result<std::string> bytes = format == v1::OCCUPANCY_FORMAT_MAVOCC
                                  ? Result<std::string>(dataset::EncodeMavocc(grid))
                                  : dataset::EncodeOctomapBt(grid);
  if (!bytes.ok()) return ToGrpcStatus(bytes.status());
  const dataset::GridGeometry& g = grid.geometry();
  return StreamChunks(context, *bytes, chunk_bytes, [&](v1::FileChunk&& chunk, bool first) {
    v1::OccupancyChunk message;
    *message.mutable_chunk() = std::move(chunk);
    if (first) {
      message.set_format(format);
      message.set_resolution_m(g.resolution);
      const Eigen::Vector3d max = g.max_corner();
      v1::Box* box = message.mutable_bounds();
      box->mutable_min()->set_x(g.origin.x());
      box->mutable_min()->set_y(g.origin.y());
      box->mutable_min()->set_z(g.origin.z());
      box->mutable_max()->set_x(max.x());
      box->mutable_max()->set_y(max.y());
      box->mutable_max()->set_z(max.z());
    }
    return writer->Write(message);
  });
}

}  // namespace mav::service_common
