# The libFuzzer targets (clang only): included by tests/fuzz/CMakeLists.txt when the project's
# compiler is clang, and by tests/fuzz/standalone/CMakeLists.txt for a separate clang build.
# Needs AGV_FUZZ_ROOT = the project source root.
set(_agv_fuzz_flags -fsanitize=fuzzer,address -fno-omit-frame-pointer -g)
add_library(agv_fuzz_protocol STATIC
  ${AGV_FUZZ_ROOT}/core/src/status.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/telegram_framer.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/cola_a_scan.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/nav350.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/plc_register_map.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/modbus_request.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/canopen_encoders.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/sdo.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/cia402.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/cia402_drive.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/velodyne_packet.cpp
  ${AGV_FUZZ_ROOT}/drivers/protocol/src/ouster_packet.cpp
  ${AGV_FUZZ_ROOT}/core/src/lidar3d/laser_intrinsics.cpp)
target_include_directories(agv_fuzz_protocol PUBLIC ${AGV_FUZZ_ROOT}/core/include ${AGV_FUZZ_ROOT}/hal/include
                                                    ${AGV_FUZZ_ROOT}/drivers/protocol/include)
target_link_libraries(agv_fuzz_protocol PUBLIC Eigen3::Eigen)
target_compile_features(agv_fuzz_protocol PUBLIC cxx_std_17)
target_compile_options(agv_fuzz_protocol PRIVATE -fsanitize=fuzzer-no-link,address -fno-omit-frame-pointer -g)
target_link_options(agv_fuzz_protocol INTERFACE -fsanitize=address)
foreach(_t cola_a nav350 canopen cia402 modbus velodyne ouster)
  add_executable(fuzz_${_t} ${AGV_FUZZ_ROOT}/tests/fuzz/fuzz_${_t}.cpp)
  target_link_libraries(fuzz_${_t} PRIVATE agv_fuzz_protocol)
  target_compile_options(fuzz_${_t} PRIVATE ${_agv_fuzz_flags})
  target_link_options(fuzz_${_t} PRIVATE ${_agv_fuzz_flags})
endforeach()

# agvnav-vehicle's configuration parser, with what it calls: the report library's number parser and
# file reader, and the Linux drivers (laser model defaults). Exceptions on: it is application code.
add_executable(fuzz_vehicle_config
  ${AGV_FUZZ_ROOT}/tests/fuzz/fuzz_vehicle_config.cpp
  ${AGV_FUZZ_ROOT}/apps/vehicle/vehicle_config.cpp
  ${AGV_FUZZ_ROOT}/apps/lib/report/src/number.cpp
  ${AGV_FUZZ_ROOT}/apps/lib/report/src/text_file.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/can_error.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/monotonic_clock.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/socketcan_bus.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/tcp_stream.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/sick_laser_client.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/canopen_encoder_source.cpp
  ${AGV_FUZZ_ROOT}/drivers/linux/src/sick_laser_source.cpp)
target_include_directories(fuzz_vehicle_config PRIVATE ${AGV_FUZZ_ROOT}/apps/vehicle ${AGV_FUZZ_ROOT}/apps/lib/report/include
                                                       ${AGV_FUZZ_ROOT}/apps/lib/calibration/include
                                                       ${AGV_FUZZ_ROOT}/drivers/linux/include ${AGV_FUZZ_ROOT}/tests/fuzz)
target_link_libraries(fuzz_vehicle_config PRIVATE agv_fuzz_protocol)
target_compile_options(fuzz_vehicle_config PRIVATE ${_agv_fuzz_flags})
target_link_options(fuzz_vehicle_config PRIVATE ${_agv_fuzz_flags})

# The Velodyne calibration-file parsers (db.xml, ROS YAML) with the report library's number parser
# and file reader (host code, exceptions on).
foreach(_t velodyne_yaml velodyne_dbxml)
  add_executable(fuzz_${_t}
    ${AGV_FUZZ_ROOT}/tests/fuzz/fuzz_velodyne_calibration.cpp
    ${AGV_FUZZ_ROOT}/apps/lib/datasets/src/velodyne_calibration.cpp
    ${AGV_FUZZ_ROOT}/apps/lib/report/src/number.cpp
    ${AGV_FUZZ_ROOT}/apps/lib/report/src/text_file.cpp)
  target_include_directories(fuzz_${_t} PRIVATE ${AGV_FUZZ_ROOT}/apps/lib/datasets/include
                                                ${AGV_FUZZ_ROOT}/apps/lib/report/include ${AGV_FUZZ_ROOT}/tests/fuzz)
  target_link_libraries(fuzz_${_t} PRIVATE agv_fuzz_protocol)
  target_compile_options(fuzz_${_t} PRIVATE ${_agv_fuzz_flags})
  target_link_options(fuzz_${_t} PRIVATE ${_agv_fuzz_flags})
endforeach()
target_compile_definitions(fuzz_velodyne_dbxml PRIVATE AGV_FUZZ_DBXML)

# The landmark map and calibration file parsers of the core (text formats, versions 1 and 2).
add_executable(fuzz_vehicle_files
  ${AGV_FUZZ_ROOT}/tests/fuzz/fuzz_vehicle_files.cpp
  ${AGV_FUZZ_ROOT}/core/src/text_format.cpp
  ${AGV_FUZZ_ROOT}/core/src/localization/landmark_map.cpp
  ${AGV_FUZZ_ROOT}/core/src/localization/landmark_map_io.cpp
  ${AGV_FUZZ_ROOT}/core/src/calib/calibration_file.cpp)
target_include_directories(fuzz_vehicle_files PRIVATE ${AGV_FUZZ_ROOT}/tests/fuzz)
target_link_libraries(fuzz_vehicle_files PRIVATE agv_fuzz_protocol)
target_compile_options(fuzz_vehicle_files PRIVATE ${_agv_fuzz_flags})
target_link_options(fuzz_vehicle_files PRIVATE ${_agv_fuzz_flags})
