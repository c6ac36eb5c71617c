// The fault table: spec §3.2.2 (MC), §3.3.3 (BMS), §3.4.1 (OBC), §3.5.1 (IOT), §3.6.2 (locks),
// §5.2 (V3.0 HMI) and the display codes of §4. Masks are in the normalised word: the
// documented high group is shifted into the high 16 bits.
//
// Severity policy: protections, hardware faults, MOS shorts and MCU faults are critical (assist
// stops or the pack is cut off); sensor faults, communication faults and BMS alarms are
// warnings; reserved bits are info. Every [G] reading is marked uncertain.

#include "motinova/faults.h"

#include <algorithm>

namespace motinova {
namespace {

constexpr uint32_t hi(uint32_t group_bit) {
  return group_bit << 16;
}

constexpr auto kMc = FaultSource::kMc;
constexpr auto kBms = FaultSource::kBms;
constexpr auto kObc = FaultSource::kObc;
constexpr auto kIot = FaultSource::kIot;
constexpr auto kLock = FaultSource::kLock;
constexpr auto kHmi = FaultSource::kHmi;
constexpr auto kInfo = Severity::kInfo;
constexpr auto kWarn = Severity::kWarning;
constexpr auto kCrit = Severity::kCritical;

// MC 0x1104: low group listed first = low word (§3.2.2, U3, U6).
constexpr FaultDef kMcFaults[] = {
    {kMc, 0x0001, 10, "over_current_protect", "Over Current Protect", kCrit, false},
    {kMc, 0x0002, 11, "under_voltage_protect", "Under Voltage Protect", kCrit, false},
    {kMc, 0x0004, 12, "over_voltage_protect", "Over Voltage Protect", kCrit, false},
    {kMc, 0x0008, 13, "rotor_locked", "Rotor Locked", kCrit, false},
    {kMc, 0x0010, 14, "over_heat_protect", "Over Heat Protect", kCrit, false},
    {kMc, 0x0020, 16, "speed_sensor_fault", "Speed Sensor Fault", kWarn, false},
    {kMc, 0x0040, 17, "torque_sensor_fault", "Torque Sensor Fault", kWarn, false},
    {kMc, 0x0080, 18, "hall_or_brake_fault", "Hall/Brake Fault", kWarn, true},
    {kMc, 0x0100, 22, "phase_line_fault", "PhaseLine Fault", kCrit, true},
    {kMc, 0x0200, 15, "ntc_fault", "NTC Fault", kWarn, false},
    {kMc, 0x0400, 19, "bms_check_fault", "BMS Check Fault", kWarn, false},
    {kMc, 0x0800, 21, "hmi_check_fault", "HMI Check Fault", kWarn, false},
    {kMc, 0x1000, 20, "pbu_check_fault", "PBU Check Fault", kWarn, false},
    {kMc, 0x2000, 27, "mcu_fault", "MCU Fault", kCrit, false},
    {kMc, 0x4000, 23, "cadence_sensor_fault", "Cadence Sensor Fault", kWarn, true},
    {kMc, 0x8000, 24, "gas_sensor_fault", "Gas Sensor Fault", kWarn, true},
    {kMc, hi(0x0001), 25, "mos_short_circuit", "MOS Short Circuit", kCrit, false},
    {kMc, hi(0x0002), 26, "bus_voltage_abnormal", "Bus Voltage Abnormal", kCrit, true},
    {kMc, hi(0x0004), 28, "circuit_fault", "Circuit Fault", kCrit, true},
    {kMc, hi(0x0008), 29, "te_mcu_fault", "TE MCU Fault", kCrit, false},
    {kMc, hi(0x0010), 30, "te_circuit_fault", "TE Circuit Fault", kCrit, false},
    {kMc, hi(0x0020), 31, "iot_comm_fault", "IOT Communication Fault", kWarn, true},
    {kMc, hi(0x0040), 32, "new_fault_32", "Fault 32 (illegible)", kWarn, true},
    {kMc, hi(0x0080), 33, "reserved_fault_3", "Reserved Fault 3", kInfo, false},
};

// BMS 0x1204: group B (protections, no codes) = low word, group A (alarms 41-49) = high word
// (§3.3.3, U3, U22). Code 40 "Over Current Alarm" of §4 has no bit and is not listed.
constexpr FaultDef kBmsFaults[] = {
    {kBms, 0x0001, -1, "discharge_over_current_protect", "Discharge Over Current Protect", kCrit,
     true},
    {kBms, 0x0002, -1, "charge_over_current_protect", "Charge Over Current Protect", kCrit, true},
    {kBms, 0x0004, -1, "short_circuit_protect", "Short Circuit Protect", kCrit, false},
    {kBms, 0x0008, -1, "under_voltage_protect", "Under Voltage Protect", kCrit, true},
    {kBms, 0x0010, -1, "over_voltage_protect", "Over Voltage Protect", kCrit, false},
    {kBms, 0x0020, -1, "discharge_under_temp_protect", "Discharge Low Temperature Protect", kCrit,
     true},
    {kBms, 0x0040, -1, "discharge_over_temp_protect", "Discharge Over Heat Protect", kCrit, true},
    {kBms, 0x0080, -1, "charge_under_temp_protect", "Charge Low Temperature Protect", kCrit, false},
    {kBms, 0x0100, -1, "charge_over_temp_protect", "Charge Over Heat Protect", kCrit, false},
    {kBms, 0x0200, -1, "discharge_mos_fault", "Discharge MOS Fault", kCrit, false},
    {kBms, 0x0400, -1, "charge_mos_fault", "Charge MOS Fault", kCrit, false},
    {kBms, 0x0800, -1, "protection_bit_11", "Protection Bit 11 (illegible)", kWarn, true},
    {kBms, 0x1000, -1, "protection_bit_12", "Protection Bit 12 (illegible)", kWarn, true},
    {kBms, 0x2000, -1, "protection_bit_13", "Protection Bit 13 (illegible)", kWarn, true},
    {kBms, 0x4000, -1, "afe_fault", "AFE Fault", kCrit, false},
    {kBms, 0x8000, -1, "mcu_fault", "MCU Fault", kCrit, false},
    {kBms, hi(0x0001), 41, "charge_over_voltage_alarm", "Charge Over Voltage Alarm", kWarn, false},
    {kBms, hi(0x0002), 42, "discharge_under_voltage_alarm", "DisCharge Under Voltage Alarm", kWarn,
     false},
    {kBms, hi(0x0004), 43, "charge_over_current_alarm", "Charge Over Current Alarm", kWarn, false},
    {kBms, hi(0x0008), 44, "discharge_over_current_alarm", "DisCharge Over Current Alarm", kWarn,
     false},
    {kBms, hi(0x0010), 45, "charge_over_heat_alarm", "Charge Over Heat Alarm", kWarn, false},
    {kBms, hi(0x0020), 46, "charge_low_temp_alarm", "Charge Low Temperature Alarm", kWarn, false},
    {kBms, hi(0x0040), 47, "discharge_over_heat_alarm", "DisCharge Over Heat Alarm", kWarn, false},
    {kBms, hi(0x0080), 48, "discharge_low_temp_alarm", "Discharge Low Temperature Alarm", kWarn,
     false},
    {kBms, hi(0x0100), 49, "mos_over_heat_alarm", "MOS Over Heat Alarm", kWarn, false},
};

// OBC 0x1504: low word, codes 60-72 (§3.4.1, §4); high word reserved.
constexpr FaultDef kObcFaults[] = {
    {kObc, 0x0001, 60, "plus_key_fault", "+ Key Fault", kWarn, false},
    {kObc, 0x0002, 61, "minus_key_fault", "- Key Fault", kWarn, false},
    {kObc, 0x0004, 62, "info_key_fault", "i Key Fault", kWarn, false},
    {kObc, 0x0008, 63, "light_key_fault", "Light Key Fault", kWarn, false},
    {kObc, 0x0010, 64, "walk_key_fault", "Walk Key Fault", kWarn, false},
    {kObc, 0x0020, 65, "power_key_fault", "Power Key Fault", kWarn, false},
    {kObc, 0x0040, 66, "mcu_fault", "MCU Fault", kCrit, false},
    {kObc, 0x0080, 67, "mos_short_circuit", "MOS Short Circuit", kCrit, false},
    {kObc, 0x0100, 68, "voltage_test_fault", "Voltage Test Fault", kWarn, false},
    {kObc, 0x0200, 69, "hmi_comm_fault", "HMI Communication Fault", kWarn, false},
    {kObc, 0x0400, 70, "mc_comm_fault", "MC Communication Fault", kWarn, false},
    {kObc, 0x0800, 71, "reserved_fault_1", "Reserved Fault 1", kInfo, false},
    {kObc, 0x1000, 72, "reserved_fault_2", "Reserved Fault 2", kInfo, false},
};

// IOT 0x1504: our own bits (U18: the gateway defines them; GPS stays at 0x0004).
constexpr FaultDef kIotFaults[] = {
    {kIot, 0x0001, -1, "lte_module", "LTE Module Fault", kWarn, true},
    {kIot, 0x0002, -1, "ble_module", "BLE Module Fault", kWarn, true},
    {kIot, 0x0004, -1, "gps", "GPS Fault", kWarn, false},
    {kIot, 0x0008, -1, "unknown", "Unknown IOT Fault", kWarn, true},
};

// Lock 0x1104: low word (§3.6.2); bits 0x0008-0x0040 are U20.
constexpr FaultDef kLockFaults[] = {
    {kLock, 0x0001, -1, "over_current", "Over Current", kCrit, false},
    {kLock, 0x0002, -1, "under_voltage", "Under Voltage", kCrit, false},
    {kLock, 0x0004, -1, "over_voltage", "Over Voltage", kCrit, false},
    {kLock, 0x0008, -1, "position_switch_fault", "Position Switch Fault", kWarn, true},
    {kLock, 0x0010, -1, "over_temperature", "Over Temperature", kCrit, true},
    {kLock, 0x0020, -1, "comm_or_sensor_fault", "Communication/Sensor Fault", kWarn, true},
    {kLock, 0x0040, -1, "motor_stall", "Motor Stall", kWarn, true},
};

// V3.0 HMI 0x1404 (§5.2): 0x0004/0x0008 are illegible; the two HMI codes of §4 (80, 81) are
// the only HMI faults left without a bit, so they are placed there as a guess.
constexpr FaultDef kHmiFaults[] = {
    {kHmi, 0x0001, -1, "lcd_fault", "LCD Fault", kWarn, false},
    {kHmi, 0x0002, -1, "mcu_fault", "MCU Fault", kCrit, false},
    {kHmi, 0x0004, 80, "mc_comm_fault", "MC Communication Fault", kWarn, true},
    {kHmi, 0x0008, 81, "pbu_comm_fault", "PBU Communication Fault", kWarn, true},
};

// Tables are kept in bit order so that fault_table() lists bits low to high.
constexpr bool in_bit_order(std::span<const FaultDef> table) {
  for (std::size_t i = 1; i < table.size(); ++i) {
    if (table[i - 1].mask >= table[i].mask) return false;
  }
  return true;
}
static_assert(in_bit_order(kMcFaults) && in_bit_order(kBmsFaults) && in_bit_order(kObcFaults) &&
              in_bit_order(kIotFaults) && in_bit_order(kLockFaults) && in_bit_order(kHmiFaults));

}  // namespace

std::string_view fault_source_name(FaultSource s) {
  switch (s) {
    case FaultSource::kMc:
      return "mc";
    case FaultSource::kBms:
      return "bms";
    case FaultSource::kObc:
      return "obc";
    case FaultSource::kIot:
      return "iot";
    case FaultSource::kLock:
      return "lock";
    case FaultSource::kHmi:
      return "hmi";
  }
  return "unknown";
}

std::string_view severity_name(Severity s) {
  switch (s) {
    case Severity::kInfo:
      return "info";
    case Severity::kWarning:
      return "warning";
    case Severity::kCritical:
      return "critical";
  }
  return "unknown";
}

std::span<const FaultDef> fault_table(FaultSource source) {
  switch (source) {
    case FaultSource::kMc:
      return kMcFaults;
    case FaultSource::kBms:
      return kBmsFaults;
    case FaultSource::kObc:
      return kObcFaults;
    case FaultSource::kIot:
      return kIotFaults;
    case FaultSource::kLock:
      return kLockFaults;
    case FaultSource::kHmi:
      return kHmiFaults;
  }
  return {};
}

const FaultDef* find_fault(FaultSource source, uint32_t mask) {
  const auto table = fault_table(source);
  const auto it = std::lower_bound(table.begin(), table.end(), mask,
                                   [](const FaultDef& d, uint32_t m) { return d.mask < m; });
  return it != table.end() && it->mask == mask ? &*it : nullptr;
}

}  // namespace motinova
