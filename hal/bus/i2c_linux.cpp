#include "hal/bus/i2c_linux.h"

#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace rilo::hal {
namespace {

std::string devicePath(const std::string& bus_path, std::uint8_t address) {
  char suffix[8];
  std::snprintf(suffix, sizeof suffix, "@0x%02x", static_cast<unsigned>(address));
  return bus_path + suffix;
}

std::error_code lastError() noexcept { return {errno, std::system_category()}; }

}  // namespace

I2cLinux::I2cLinux(std::string bus_path, std::uint8_t address, std::size_t max_message_bytes)
    : path_(devicePath(bus_path, address)), address_(address) {
  if (address < 0x08 || address > 0x77) {
    throw std::invalid_argument("I2cLinux: address " + path_ + " is not a 7-bit device address (0x08..0x77)");
  }
  if (max_message_bytes < 2 || max_message_bytes > kKernelMaxMessageBytes) {
    throw std::invalid_argument("I2cLinux: max_message_bytes must be 2..8192, got " +
                                std::to_string(max_message_bytes));
  }
  fd_ = ::open(bus_path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) {
    const int err = errno;
    throw std::runtime_error("I2C: cannot open " + bus_path + " (for " + path_ + "): " + std::strerror(err));
  }
  unsigned long funcs = 0;
  if (::ioctl(fd_, I2C_FUNCS, &funcs) < 0) {
    const int err = errno;
    ::close(fd_);
    throw std::runtime_error("I2C: " + bus_path + " is not an i2c-dev adapter (I2C_FUNCS failed): " +
                             std::strerror(err));
  }
  if ((funcs & I2C_FUNC_I2C) == 0) {
    ::close(fd_);
    throw std::runtime_error("I2C: adapter " + bus_path +
                             " does not support plain I2C messages (I2C_RDWR, repeated start)");
  }
  write_buffer_.resize(max_message_bytes);
}

I2cLinux::~I2cLinux() {
  if (fd_ >= 0) ::close(fd_);
}

std::error_code I2cLinux::readRegisters(std::uint8_t reg, std::span<std::uint8_t> out) noexcept {
  if (out.empty()) return {};
  if (out.size() > kKernelMaxMessageBytes) return std::make_error_code(std::errc::message_size);
  std::uint8_t reg_byte = reg;
  i2c_msg msgs[2] = {};
  msgs[0].addr = address_;
  msgs[0].flags = 0;
  msgs[0].len = 1;
  msgs[0].buf = &reg_byte;
  msgs[1].addr = address_;
  msgs[1].flags = I2C_M_RD;  // no I2C_M_STOP between: the kernel joins them with a repeated start
  msgs[1].len = static_cast<std::uint16_t>(out.size());
  msgs[1].buf = out.data();
  i2c_rdwr_ioctl_data data{};
  data.msgs = msgs;
  data.nmsgs = 2;
  const int done = ::ioctl(fd_, I2C_RDWR, &data);
  if (done < 0) return lastError();
  if (done != 2) return std::make_error_code(std::errc::io_error);
  return {};
}

std::error_code I2cLinux::transferOne(std::uint8_t reg, std::span<const std::uint8_t> chunk) noexcept {
  write_buffer_[0] = reg;
  if (!chunk.empty()) std::memcpy(write_buffer_.data() + 1, chunk.data(), chunk.size());
  i2c_msg msg{};
  msg.addr = address_;
  msg.flags = 0;
  msg.len = static_cast<std::uint16_t>(chunk.size() + 1);
  msg.buf = write_buffer_.data();
  i2c_rdwr_ioctl_data data{};
  data.msgs = &msg;
  data.nmsgs = 1;
  const int done = ::ioctl(fd_, I2C_RDWR, &data);
  if (done < 0) return lastError();
  if (done != 1) return std::make_error_code(std::errc::io_error);
  return {};
}

std::error_code I2cLinux::writeRegisters(std::uint8_t reg, std::span<const std::uint8_t> data) noexcept {
  const std::size_t chunk_max = write_buffer_.size() - 1;
  if (data.size() <= chunk_max) return transferOne(reg, data);
  if (static_cast<std::size_t>(reg) + data.size() > 0x100) return std::make_error_code(std::errc::invalid_argument);
  for (std::size_t offset = 0; offset < data.size(); offset += chunk_max) {
    const std::size_t n = std::min(chunk_max, data.size() - offset);
    const std::error_code error = transferOne(static_cast<std::uint8_t>(reg + offset), data.subspan(offset, n));
    if (error) return error;
  }
  return {};
}

}  // namespace rilo::hal
