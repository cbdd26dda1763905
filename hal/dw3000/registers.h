#pragma once
// DW3000 register map: the subset this driver uses, as (file, offset) pairs,
// status bits and fast commands. Source: docs/hardware-notes.md section 1;
// entries marked "Qorvo driver" come from Qorvo's public DW3000 driver and
// are not in the notes (UNVERIFIED on our hardware).
#include <cstdint>

namespace rilo::dw3000 {

/// A register address: 5-bit file (0x00-0x1F) and 7-bit offset (buffers
/// files may be read past offset 0x7F by continuing a burst).
struct RegAddr {
  std::uint8_t file = 0;
  std::uint8_t offset = 0;
  friend constexpr bool operator==(RegAddr a, RegAddr b) { return a.file == b.file && a.offset == b.offset; }
  /// The register's byte `bytes` further on (a byte or field inside it).
  constexpr RegAddr plus(int bytes) const { return RegAddr{file, static_cast<std::uint8_t>(offset + bytes)}; }
};

namespace reg {
inline constexpr RegAddr kDevId{0x00, 0x00};      ///< 4 bytes, 0xDECA0302 / 0xDECA0312
inline constexpr RegAddr kPanAdr{0x00, 0x0C};     ///< short address (15:0), PAN id (31:16) (Qorvo driver)
inline constexpr RegAddr kSysCfg{0x00, 0x10};     ///< 4 bytes
inline constexpr RegAddr kSpiRdCrc{0x00, 0x18};   ///< CRC-8 of the last read (Qorvo driver: SPICRC_CFG)
inline constexpr RegAddr kSysTime{0x00, 0x1C};    ///< 4 bytes: device time bits 39:8
inline constexpr RegAddr kTxFctrl{0x00, 0x24};    ///< 4 (+2) bytes
inline constexpr RegAddr kDxTime{0x00, 0x2C};     ///< 4 bytes: delayed TX/RX time bits 39:8
inline constexpr RegAddr kRxFwto{0x00, 0x34};     ///< frame wait timeout, bits 19:0, UWB microseconds (Qorvo driver)
inline constexpr RegAddr kSysEnable{0x00, 0x3C};  ///< interrupt mask, low 32 bits
inline constexpr RegAddr kSysEnableHi{0x00, 0x40};  ///< interrupt mask, high 16 bits
inline constexpr RegAddr kSysStatus{0x00, 0x44};  ///< 4 bytes low + 2 bytes high at 0x48; write 1 to clear
inline constexpr RegAddr kSysStatusHi{0x00, 0x48};
inline constexpr RegAddr kRxFinfo{0x00, 0x4C};    ///< length bits 9:0 (includes the 2-byte FCS)
inline constexpr RegAddr kRxTime{0x00, 0x64};     ///< 5 bytes, RX antenna delay applied
inline constexpr RegAddr kTxTime{0x00, 0x74};     ///< 5 bytes
inline constexpr RegAddr kTxAntd{0x01, 0x04};     ///< 2 bytes, TX antenna delay (device units)
inline constexpr RegAddr kAckResp{0x01, 0x08};    ///< W4R_TIM bits 19:0 (RX-after-TX delay, UWB microseconds)
inline constexpr RegAddr kChanCtrl{0x01, 0x14};   ///< RF_CHAN b0, SFD_TYPE b2:1, TX_PCODE b7:3, RX_PCODE b12:8
inline constexpr RegAddr kDgcCfg{0x03, 0x18};    ///< RX_TUNE_EN b0: DGC on (Qorvo driver)
inline constexpr RegAddr kDgcDbg{0x03, 0x60};    ///< DGC_DECISION bits 30:28 (Qorvo driver, C0 parts)
inline constexpr RegAddr kDrxDiag3{0x06, 0x29};   ///< carrier integrator, 21-bit signed (3 bytes read)
inline constexpr RegAddr kXtalTrim{0x09, 0x14};
inline constexpr RegAddr kCiaDiag0{0x0C, 0x20};   ///< clock offset bits 12:0 signed, ratio = value / 2^26
inline constexpr RegAddr kIpDiag1{0x0C, 0x2C};    ///< C (CIR power); IP_DIAG_2..4 (F1..F3) follow, IP_DIAG_12 (N) at 0x58 (Qorvo driver)
inline constexpr RegAddr kCiaConf{0x0E, 0x00};    ///< RX antenna delay bits 15:0
inline constexpr RegAddr kSysState{0x0F, 0x30};
inline constexpr RegAddr kSoftRst{0x11, 0x00};
inline constexpr RegAddr kRxBuffer0{0x12, 0x00};
inline constexpr RegAddr kRxBuffer1{0x13, 0x00};
inline constexpr RegAddr kTxBuffer{0x14, 0x00};

// Start-up registers (Qorvo's C0 API v04.00.00, deca_regs.h; bring_up.cpp
// names the API function each write follows).
inline constexpr RegAddr kTxFctrlHi{0x00, 0x28};   ///< FINE_PLEN bits 15:8 (byte 0x29)
inline constexpr RegAddr kTxPower{0x01, 0x0C};     ///< 4 x 8-bit power settings
inline constexpr RegAddr kRdbDiagMode{0x01, 0x28}; ///< RDB_DMODE bits 2:0
inline constexpr RegAddr kStsCfg0{0x02, 0x00};     ///< CPS_LEN bits 7:0 (STS length - 1)
inline constexpr RegAddr kDgcCfg0{0x03, 0x1C};
inline constexpr RegAddr kDgcCfg1{0x03, 0x20};
inline constexpr RegAddr kDgcLut0{0x03, 0x38};     ///< DGC_LUT_0..6 at 0x38..0x50, 4 bytes apart
inline constexpr RegAddr kRxCalCfg{0x04, 0x0C};    ///< CAL_MODE 1:0, CAL_EN b4, COMP_DLY 19:16
inline constexpr RegAddr kRxCalResI{0x04, 0x14};
inline constexpr RegAddr kRxCalResQ{0x04, 0x1C};
inline constexpr RegAddr kRxCalSts{0x04, 0x20};    ///< 1 when the PGF calibration is done
inline constexpr RegAddr kDtune0{0x06, 0x00};      ///< PRE_PAC_SYM 1:0; SFD timeout 31:16 (bytes 0x02..0x03)
inline constexpr RegAddr kDtune0SfdTimeout{0x06, 0x02};
inline constexpr RegAddr kDtune3{0x06, 0x0C};      ///< preamble detection threshold
inline constexpr RegAddr kRxCtrlHi{0x07, 0x10};
inline constexpr RegAddr kTxCtrlLo{0x07, 0x18};
inline constexpr RegAddr kTxCtrlHi{0x07, 0x1C};    ///< TX_PG_DELAY bits 5:0
inline constexpr RegAddr kLdoTuneLo{0x07, 0x40};   ///< loaded from OTP by the LDO kick
inline constexpr RegAddr kLdoTuneHi{0x07, 0x44};
inline constexpr RegAddr kLdoCtrl{0x07, 0x48};
inline constexpr RegAddr kLdoRload{0x07, 0x50};
inline constexpr RegAddr kPllCfg{0x09, 0x00};      ///< 16 bits
inline constexpr RegAddr kPllCal{0x09, 0x08};
inline constexpr RegAddr kAonDigCfg{0x0A, 0x00};
inline constexpr RegAddr kAonCtrl{0x0A, 0x04};     ///< ARRAY_SAVE b1
inline constexpr RegAddr kAnaCfg{0x0A, 0x14};
inline constexpr RegAddr kOtpAddr{0x0B, 0x04};     ///< bits 10:0
inline constexpr RegAddr kOtpCfg{0x0B, 0x08};
inline constexpr RegAddr kOtpRdata{0x0B, 0x10};
inline constexpr RegAddr kClkCtrl{0x11, 0x04};     ///< SYS_CLK_SEL bits 1:0
inline constexpr RegAddr kSeqCtrl{0x11, 0x08};     ///< AINIT2IDLE b8
inline constexpr RegAddr kBiasCtrl{0x11, 0x1F};    ///< BIAS bits 4:0
}  // namespace reg

/// OTP words read at start-up (word addresses; dwt_initialise).
namespace otp {
inline constexpr std::uint16_t kLdoTuneLo = 0x04;
inline constexpr std::uint16_t kLdoTuneHi = 0x05;
inline constexpr std::uint16_t kPartId = 0x06;
inline constexpr std::uint16_t kLotId = 0x07;
inline constexpr std::uint16_t kBiasTune = 0x0A;  ///< bias trim in bits 20:16
inline constexpr std::uint16_t kXtalTrim = 0x1E;  ///< bits 6:0; 0 = not programmed
inline constexpr std::uint16_t kRevision = 0x1F;
inline constexpr std::uint16_t kDgcTune = 0x20;   ///< equals kDgcCfg0Value when the DGC table is in OTP
/// XTAL trim the API writes when OTP holds none (mid-range).
inline constexpr std::uint8_t kDefaultXtalTrim = 0x2E;
}  // namespace otp

/// OTP_CFG bits (deca_regs.h).
namespace otp_cfg {
inline constexpr std::uint32_t kManualEnable = 1u << 0;
inline constexpr std::uint32_t kRead = 1u << 1;
inline constexpr std::uint32_t kDgcKick = 1u << 6;
inline constexpr std::uint32_t kLdoKick = 1u << 7;
inline constexpr std::uint32_t kBiasKick = 1u << 8;
inline constexpr std::uint32_t kOpsKick = 1u << 10;
inline constexpr std::uint32_t kOpsIdMask = 0x3u << 11;
inline constexpr std::uint32_t kOpsLong = 0x0u << 11;   ///< preambles of 256 symbols and more
inline constexpr std::uint32_t kOpsShort = 0x2u << 11;  ///< shorter preambles
inline constexpr std::uint32_t kDgcSelCh9 = 1u << 13;
}  // namespace otp_cfg

/// DEV_ID values of the parts we accept.
inline constexpr std::uint32_t kDevIdDw3110 = 0xDECA0302;
inline constexpr std::uint32_t kDevIdDw3120 = 0xDECA0312;

/// SYS_CFG bits (Qorvo driver names; SPI_CRC is in the notes).
namespace sys_cfg {
inline constexpr std::uint32_t kPhr6M8 = 1u << 5;   ///< PHR at 6.8 Mb/s (Qorvo driver)
inline constexpr std::uint32_t kSpiCrc = 1u << 6;   ///< SPI CRC check enable
inline constexpr std::uint32_t kRxWtoe = 1u << 9;   ///< RX frame wait timeout enable (Qorvo driver)
}  // namespace sys_cfg

/// TX_FCTRL fields (Qorvo driver): TXFLEN 9:0, TXBR b10 (6.8 Mb/s), TR b11
/// (ranging frame), TXPSR 15:12 (preamble length code).
namespace tx_fctrl {
inline constexpr std::uint32_t kLengthMask = 0x3FF;
inline constexpr std::uint32_t kBr6M8 = 1u << 10;
inline constexpr std::uint32_t kRanging = 1u << 11;
inline constexpr int kPsrShift = 12;
}  // namespace tx_fctrl

/// SYS_STATUS bits (low 32-bit word).
namespace status {
inline constexpr std::uint32_t kIrqs = 1u << 0;
inline constexpr std::uint32_t kCpLock = 1u << 1;
inline constexpr std::uint32_t kSpiCrcE = 1u << 2;
inline constexpr std::uint32_t kTxFrs = 1u << 7;
inline constexpr std::uint32_t kRxPrd = 1u << 8;
inline constexpr std::uint32_t kRxSfdd = 1u << 9;
inline constexpr std::uint32_t kCiaDone = 1u << 10;
inline constexpr std::uint32_t kRxPhd = 1u << 11;
inline constexpr std::uint32_t kRxPhe = 1u << 12;
inline constexpr std::uint32_t kRxFr = 1u << 13;
inline constexpr std::uint32_t kRxFcg = 1u << 14;
inline constexpr std::uint32_t kRxFce = 1u << 15;
inline constexpr std::uint32_t kRxFsl = 1u << 16;
inline constexpr std::uint32_t kRxFto = 1u << 17;
inline constexpr std::uint32_t kCiaErr = 1u << 18;
inline constexpr std::uint32_t kRxOvrr = 1u << 20;
inline constexpr std::uint32_t kRxPto = 1u << 21;
inline constexpr std::uint32_t kSpiRdy = 1u << 23;
inline constexpr std::uint32_t kRcInit = 1u << 24;
inline constexpr std::uint32_t kRxSto = 1u << 26;
inline constexpr std::uint32_t kHpdWarn = 1u << 27;
inline constexpr std::uint32_t kCpErr = 1u << 28;
inline constexpr std::uint32_t kArfe = 1u << 29;

/// Reception failed: header/FCS/sync errors, overrun, CIA failure.
inline constexpr std::uint32_t kAllRxErrors = kRxPhe | kRxFce | kRxFsl | kRxSto | kArfe | kCiaErr | kRxOvrr;
/// Receiver gave up waiting: frame wait or preamble detection timeout.
inline constexpr std::uint32_t kAllRxTimeouts = kRxFto | kRxPto;
/// Every event a ranging exchange can leave behind (cleared after each one).
inline constexpr std::uint32_t kAllTxRxEvents = kTxFrs | kRxPrd | kRxSfdd | kCiaDone | kRxPhd | kRxFr | kRxFcg |
                                                kAllRxErrors | kAllRxTimeouts;
}  // namespace status

/// Values of the vendor's start-up (deca_vals.h of the C0 API v04.00.00).
namespace startup {
inline constexpr std::uint32_t kDtune3Default = 0xAF5F584C;  ///< PD_THRESH_DEFAULT (STS off)
inline constexpr std::uint16_t kPllCfgCh5 = 0x1F3C;
inline constexpr std::uint16_t kPllCfgCh9 = 0x0F3C;
inline constexpr std::uint32_t kTxCtrlHiCh5 = 0x1C071134;
inline constexpr std::uint32_t kTxCtrlHiCh9 = 0x1C010034;
inline constexpr std::uint32_t kRxCtrlHiCh9 = 0x08B5A833;  ///< channel 5 keeps the reset value
inline constexpr std::uint8_t kLdoRloadByte1 = 0x14;
inline constexpr std::uint8_t kTxCtrlLoByte2 = 0x0E;
inline constexpr std::uint8_t kPllCalByte0 = 0x81;          ///< RF_PLL_CFG_LD: longer lock delay
inline constexpr std::uint16_t kAutoClocks = 0x0200;        ///< CLK_CTRL low half, DWT_AUTO_CLKS
inline constexpr std::uint8_t kForceSysClkFosc = 0x03;      ///< CLK_CTRL SYS_CLK_SEL = FOSC
inline constexpr std::uint32_t kAinit2Idle = 1u << 8;       ///< SEQ_CTRL
inline constexpr std::uint32_t kDgcCfg0Value = 0x10000240;
inline constexpr std::uint32_t kDgcCfg1Value = 0x1B6DA489;
inline constexpr std::uint32_t kDgcThr64 = 0x32;            ///< DGC_CFG bits 14:9
inline constexpr std::uint32_t kDgcThr64Mask = 0x3Fu << 9;
inline constexpr std::uint32_t kDgcRxTuneEn = 1u << 0;
inline constexpr std::uint32_t kDgcLutCh5[7] = {0x1C0FD, 0x1C43E, 0x1C6BE, 0x1C77E, 0x1CF36, 0x1CFB5, 0x1CFF5};
inline constexpr std::uint32_t kDgcLutCh9[7] = {0x2A8FE, 0x2AC36, 0x2A5FE, 0x2AF3E, 0x2AF7D, 0x2AFB5, 0x2AFB5};
inline constexpr std::uint32_t kLdoCtrlForPgf = 0x0105;     ///< VDDIF2 | VDDMS3 | VDDMS1
inline constexpr std::uint32_t kRxCalCfgPgf = 0x00020001;   ///< COMP_DLY 2, CAL_MODE 1
inline constexpr std::uint32_t kRxCalEnable = 1u << 4;
inline constexpr std::uint32_t kRxCalFailed = 0x1FFFFFFF;   ///< ERR_RX_CAL_FAIL in RX_CAL_RESI / RESQ
inline constexpr std::uint32_t kCiaMinDiag = 1u << 20;      ///< CIA_CONF: minimal diagnostics (IP_DIAG not logged)
inline constexpr std::uint8_t kStsCfg0Len64 = 0x07;         ///< 64-symbol STS - 1 (written with the STS off too)
}  // namespace startup

/// Fast commands (`0x81 | cmd << 1`).
namespace fast_cmd {
inline constexpr std::uint8_t kTxRxOff = 0x00;
inline constexpr std::uint8_t kTx = 0x01;
inline constexpr std::uint8_t kRx = 0x02;
inline constexpr std::uint8_t kDtx = 0x03;
inline constexpr std::uint8_t kDrx = 0x04;
inline constexpr std::uint8_t kTxW4r = 0x0C;
inline constexpr std::uint8_t kDtxW4r = 0x0D;
inline constexpr std::uint8_t kClrIrqs = 0x12;
}  // namespace fast_cmd

}  // namespace rilo::dw3000
