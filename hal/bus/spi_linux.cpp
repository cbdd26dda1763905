#include "hal/bus/spi_linux.h"

#include <fcntl.h>
#include <linux/spi/spidev.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace rilo::hal {
namespace {

// SPI_IOC_MESSAGE(n) sizes a char array by n: only constant n is valid C++,
// so the requests for 1..kMaxTransfers are built once at compile time.
template <std::size_t... I>
constexpr std::array<unsigned long, sizeof...(I)> messageRequests(std::index_sequence<I...>) {
  return {static_cast<unsigned long>(SPI_IOC_MESSAGE(I + 1))...};
}
constexpr auto kMessageRequest = messageRequests(std::make_index_sequence<SpiLinux::kMaxTransfers>{});

std::error_code lastError() noexcept { return {errno, std::system_category()}; }

[[noreturn]] void throwSetupError(const std::string& path, const char* step, int error_number) {
  throw std::runtime_error("spidev " + path + ": " + step + " failed: " + std::strerror(error_number));
}

}  // namespace

SpiLinux::SpiLinux(std::string path, std::uint32_t speed_hz) : path_(std::move(path)), speed_hz_(speed_hz) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) throwSetupError(path_, "open", errno);
  // Any failure below closes the descriptor before throwing.
  const auto fail = [this](const char* step) {
    const int saved = errno;
    ::close(fd_);
    fd_ = -1;
    throwSetupError(path_, step, saved);
  };
  std::uint8_t mode = SPI_MODE_0;
  if (::ioctl(fd_, SPI_IOC_WR_MODE, &mode) < 0) fail("SPI_IOC_WR_MODE (mode 0)");
  std::uint8_t bits = 8;
  if (::ioctl(fd_, SPI_IOC_WR_BITS_PER_WORD, &bits) < 0) fail("SPI_IOC_WR_BITS_PER_WORD (8)");
  std::uint32_t speed = speed_hz_;
  if (::ioctl(fd_, SPI_IOC_WR_MAX_SPEED_HZ, &speed) < 0) fail("SPI_IOC_WR_MAX_SPEED_HZ");
}

SpiLinux::~SpiLinux() {
  if (fd_ >= 0) ::close(fd_);
}

std::error_code SpiLinux::transfer(std::span<const SpiTransfer> transfers) noexcept {
  if (transfers.empty() || transfers.size() > kMaxTransfers) {
    return std::make_error_code(std::errc::invalid_argument);
  }
  // Zero-initialized: the fields we do not set (delays, tx/rx_nbits, pad)
  // must be 0 or the kernel rejects or misinterprets the message.
  std::array<spi_ioc_transfer, kMaxTransfers> xfers{};
  for (std::size_t i = 0; i < transfers.size(); ++i) {
    const SpiTransfer& t = transfers[i];
    if (t.len > 0xFFFF'FFFFu) return std::make_error_code(std::errc::message_size);
    xfers[i].tx_buf = reinterpret_cast<std::uintptr_t>(t.tx);
    xfers[i].rx_buf = reinterpret_cast<std::uintptr_t>(t.rx);
    xfers[i].len = static_cast<std::uint32_t>(t.len);
    xfers[i].speed_hz = speed_hz_;
    xfers[i].bits_per_word = 8;
    xfers[i].cs_change = t.cs_change ? 1 : 0;
  }
  if (::ioctl(fd_, kMessageRequest[transfers.size() - 1], xfers.data()) < 0) return lastError();
  return {};
}

std::error_code SpiLinux::setSpeedHz(std::uint32_t speed_hz) noexcept {
  std::uint32_t speed = speed_hz;
  if (::ioctl(fd_, SPI_IOC_WR_MAX_SPEED_HZ, &speed) < 0) return lastError();
  speed_hz_ = speed_hz;
  return {};
}

}  // namespace rilo::hal
