#include "drivers/v4l2/v4l2_device.hpp"

#include <fcntl.h>

#include <algorithm>
#include <cstring>

#include "platform/syscall.hpp"

namespace markloop::v4l2 {

namespace {

template <std::size_t N, std::size_t M>
void copy_name(std::array<char, N>& out, const __u8 (&in)[M]) noexcept {
  const std::size_t n = std::min(N - 1, M);
  std::size_t i = 0;
  for (; i < n && in[i] != 0; ++i) out[i] = static_cast<char>(in[i]);
  out[i] = '\0';
}

}  // namespace

std::error_code V4l2Device::ioctl(unsigned long request, void* arg) noexcept {
  if (!fd_) return platform::make_error(EBADF);
  return platform::sys_ioctl(fd_.get(), request, arg);
}

std::error_code V4l2Device::open(const char* path, Direction direction, DeviceInfo& info) noexcept {
  close();
  if (path == nullptr || path[0] == '\0') return std::make_error_code(std::errc::invalid_argument);
  int raw = -1;
  if (auto ec = platform::sys_open(path, O_RDWR | O_NONBLOCK | O_CLOEXEC, raw)) return ec;
  fd_.reset(raw);
  direction_ = direction;

  v4l2_capability cap{};
  if (auto ec = ioctl(VIDIOC_QUERYCAP, &cap)) {
    fd_.reset();
    return ec;
  }
  info = DeviceInfo{};
  copy_name(info.driver, cap.driver);
  copy_name(info.card, cap.card);
  copy_name(info.bus, cap.bus_info);
  info.capabilities = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  const std::uint32_t wanted =
      direction == Direction::Capture ? V4L2_CAP_VIDEO_CAPTURE : V4L2_CAP_VIDEO_OUTPUT;
  std::error_code ec;
  if ((info.capabilities & wanted) == 0)
    ec = direction == Direction::Capture ? V4l2Error::NotACaptureDevice : V4l2Error::NotAnOutputDevice;
  else if ((info.capabilities & V4L2_CAP_STREAMING) == 0)
    ec = V4l2Error::NoStreaming;
  if (ec) fd_.reset();
  return ec;
}

void V4l2Device::close() noexcept {
  if (!fd_) return;
  if (streaming_) (void)stream_off();
  unmap_and_free();
  fd_.reset();
}

void V4l2Device::unmap_and_free() noexcept {
  for (std::size_t i = 0; i < buffer_count_; ++i) {
    platform::sys_munmap(buffers_[i].data, buffers_[i].length);
    buffers_[i] = MappedBuffer{};
  }
  buffer_count_ = 0;
  if (buffers_requested_ && fd_) {
    // Unmapped first: vb2 refuses to free buffers that are still mapped.
    v4l2_requestbuffers req{};
    req.count = 0;
    req.type = buffer_type();
    req.memory = V4L2_MEMORY_MMAP;
    (void)ioctl(VIDIOC_REQBUFS, &req);  // fails harmlessly when the device is gone
  }
  buffers_requested_ = false;
}

std::error_code V4l2Device::select_input(int index) noexcept {
  int value = index;
  return ioctl(VIDIOC_S_INPUT, &value);
}

std::error_code V4l2Device::select_output(int index) noexcept {
  int value = index;
  return ioctl(VIDIOC_S_OUTPUT, &value);
}

std::error_code V4l2Device::set_format(std::uint32_t width, std::uint32_t height, PixelFormat format,
                                       NegotiatedFormat& out) noexcept {
  v4l2_format fmt{};
  fmt.type = buffer_type();
  fmt.fmt.pix.width = width;
  fmt.fmt.pix.height = height;
  fmt.fmt.pix.pixelformat = to_fourcc(format);
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (auto ec = ioctl(VIDIOC_S_FMT, &fmt)) return ec;
  // S_FMT adjusts instead of failing: compare the reply with the request.
  if (fmt.fmt.pix.pixelformat != to_fourcc(format)) return V4l2Error::FormatRefused;
  if (fmt.fmt.pix.width != width || fmt.fmt.pix.height != height) return V4l2Error::SizeRefused;
  const std::uint64_t row = static_cast<std::uint64_t>(width) * bytes_per_pixel(format);
  const std::uint32_t stride = fmt.fmt.pix.bytesperline;
  if (stride < row || stride > row * 4 || fmt.fmt.pix.sizeimage < static_cast<std::uint64_t>(stride) * height)
    return V4l2Error::BadFormatReply;
  out.format = format;
  out.width = width;
  out.height = height;
  out.stride = stride;
  out.image_size = fmt.fmt.pix.sizeimage;
  return {};
}

std::error_code V4l2Device::set_frame_rate(std::uint32_t fps, FrameInterval& out) noexcept {
  out = FrameInterval{};
  v4l2_streamparm parm{};
  parm.type = buffer_type();
  if (auto ec = ioctl(VIDIOC_G_PARM, &parm)) {
    // Drivers without G_PARM have no rate to set.
    if (ec.value() == ENOTTY || ec.value() == EINVAL) return fps == 0 ? std::error_code{} : ec;
    return ec;
  }
  const bool capture = direction_ == Direction::Capture;
  const std::uint32_t caps = capture ? parm.parm.capture.capability : parm.parm.output.capability;
  out.settable = (caps & V4L2_CAP_TIMEPERFRAME) != 0;
  if (fps > 0 && out.settable) {
    v4l2_fract& tpf = capture ? parm.parm.capture.timeperframe : parm.parm.output.timeperframe;
    tpf.numerator = 1;
    tpf.denominator = fps;
    if (auto ec = ioctl(VIDIOC_S_PARM, &parm)) return ec;
  }
  const v4l2_fract& tpf = capture ? parm.parm.capture.timeperframe : parm.parm.output.timeperframe;
  out.numerator = tpf.numerator;
  out.denominator = tpf.denominator;
  if (fps > 0 && out.settable &&
      static_cast<std::uint64_t>(out.denominator) != static_cast<std::uint64_t>(fps) * out.numerator)
    return V4l2Error::FrameRateRefused;
  return {};
}

std::error_code V4l2Device::request_buffers(std::uint32_t count, std::uint32_t image_size) noexcept {
  if (count == 0 || count > kMaxBuffers) return std::make_error_code(std::errc::invalid_argument);
  unmap_and_free();
  v4l2_requestbuffers req{};
  req.count = count;
  req.type = buffer_type();
  req.memory = V4L2_MEMORY_MMAP;
  if (auto ec = ioctl(VIDIOC_REQBUFS, &req)) return ec;
  buffers_requested_ = req.count > 0;
  if (req.count != count) {
    const bool fewer = req.count < count;
    unmap_and_free();
    return fewer ? V4l2Error::TooFewBuffers : V4l2Error::TooManyBuffers;
  }
  for (std::uint32_t i = 0; i < count; ++i) {
    v4l2_buffer buf{};
    buf.type = buffer_type();
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    std::error_code ec = ioctl(VIDIOC_QUERYBUF, &buf);
    if (!ec && buf.length < image_size) ec = V4l2Error::BufferTooSmall;
    void* address = nullptr;
    if (!ec) ec = platform::sys_mmap_shared(fd_.get(), buf.length, static_cast<long>(buf.m.offset), address);
    if (ec) {
      unmap_and_free();
      return ec;
    }
    buffers_[i] = MappedBuffer{static_cast<std::uint8_t*>(address), buf.length};
    buffer_count_ = i + 1;
  }
  return {};
}

std::error_code V4l2Device::queue(std::uint32_t index, std::uint32_t bytes_used) noexcept {
  if (index >= buffer_count_ || bytes_used > buffers_[index].length)
    return std::make_error_code(std::errc::invalid_argument);
  v4l2_buffer buf{};
  buf.type = buffer_type();
  buf.memory = V4L2_MEMORY_MMAP;
  buf.index = index;
  buf.bytesused = bytes_used;
  buf.field = V4L2_FIELD_NONE;
  return ioctl(VIDIOC_QBUF, &buf);
}

std::error_code V4l2Device::dequeue(v4l2_buffer& out) noexcept {
  out = v4l2_buffer{};
  out.type = buffer_type();
  out.memory = V4L2_MEMORY_MMAP;
  if (auto ec = ioctl(VIDIOC_DQBUF, &out)) return ec;
  if (out.index >= buffer_count_) return std::make_error_code(std::errc::bad_message);
  return {};
}

std::error_code V4l2Device::stream_on() noexcept {
  int type = static_cast<int>(buffer_type());
  if (auto ec = ioctl(VIDIOC_STREAMON, &type)) return ec;
  streaming_ = true;
  return {};
}

std::error_code V4l2Device::stream_off() noexcept {
  int type = static_cast<int>(buffer_type());
  streaming_ = false;  // even on failure: STREAMOFF also dequeues everything
  return ioctl(VIDIOC_STREAMOFF, &type);
}

std::error_code V4l2Device::set_control(std::uint32_t id, std::int32_t value) noexcept {
  v4l2_control ctrl{};
  ctrl.id = id;
  ctrl.value = value;
  return ioctl(VIDIOC_S_CTRL, &ctrl);
}

std::error_code V4l2Device::get_control(std::uint32_t id, std::int32_t& value) noexcept {
  v4l2_control ctrl{};
  ctrl.id = id;
  if (auto ec = ioctl(VIDIOC_G_CTRL, &ctrl)) return ec;
  value = ctrl.value;
  return {};
}

}  // namespace markloop::v4l2
