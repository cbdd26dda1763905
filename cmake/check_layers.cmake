# Fails when production code includes a layer above its own
# (docs/architecture.md "Layers"). Run by every build (target rilo_layers) and
# by ctest; `cmake -DSOURCE_DIR=<checkout> -P cmake/check_layers.cmake` by hand.
#
# Each rule: a folder, then the first path components its project includes may
# start with. An include naming another project folder, or climbing with
# "../", is a violation; system and third-party includes (<...>, or a first
# component that is no project folder) are not judged.
cmake_minimum_required(VERSION 3.25)
if(NOT SOURCE_DIR)
  message(FATAL_ERROR "check_layers: set -DSOURCE_DIR=<checkout>")
endif()

set(project_prefixes math sensors hal estimation sim import runtime dds evaluation rilod apps)
set(rules
  "service/math:math"
  "service/sensors:sensors"
  "hal:hal,math,sensors"
  "service/estimation:estimation,math,sensors"
  "service/import:import,hal,math,sensors"
  "service/sim:sim,estimation,hal,math,sensors"
  "service/runtime:runtime,estimation,math,sensors"
  "service/dds:dds,runtime,estimation,math,sensors"
  "service/evaluation:evaluation,sim,estimation,hal,math,sensors"
  "service/rilod:rilod,dds,runtime,estimation,hal,math,sensors")

# Inside the estimation library, its rooms from the bottom up: an include of
# "estimation/<room>/..." from another room must name a room listed for it
# (tracking, at the top, may include every room).
set(estimation_rooms imu noise graph factors solver smoother ekf measurements assembly init tracking)
set(room_rules
  "imu:"
  "noise:"
  "graph:noise"
  "factors:graph,imu,noise"
  "solver:graph"
  "smoother:graph,solver,factors,imu,noise"
  "ekf:factors,graph,imu,noise"
  "measurements:graph,imu,noise"
  "assembly:measurements,factors,graph,imu,noise"
  "init:assembly,measurements,solver,factors,graph,imu,noise"
  "tracking:init,assembly,measurements,ekf,smoother,solver,factors,graph,imu,noise")

set(violations "")
set(files_checked 0)
foreach(rule IN LISTS rules)
  string(REPLACE ":" ";" parts "${rule}")
  list(GET parts 0 folder)
  list(GET parts 1 allowed)
  string(REPLACE "," ";" allowed "${allowed}")
  file(GLOB_RECURSE files "${SOURCE_DIR}/${folder}/*.h" "${SOURCE_DIR}/${folder}/*.cpp")
  foreach(file IN LISTS files)
    math(EXPR files_checked "${files_checked} + 1")
    file(RELATIVE_PATH rel "${SOURCE_DIR}" "${file}")
    # One list element per line: CMake lists split on ';' and keep '[...]'
    # together, so both are neutralised first (a comment's "[0, 1)" would
    # otherwise hide the includes after it).
    file(READ "${file}" text)
    string(REPLACE ";" "," text "${text}")
    string(REPLACE "[" "(" text "${text}")
    string(REPLACE "]" ")" text "${text}")
    string(REPLACE "\n" ";" lines "${text}")
    set(line_no 0)
    foreach(line IN LISTS lines)
      math(EXPR line_no "${line_no} + 1")
      if(line MATCHES "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\"")
        set(target "${CMAKE_MATCH_1}")
      elseif(line MATCHES "^[ \t]*#[ \t]*include[ \t]*<([^>]+)>")
        # A project header in angle brackets is judged too (Cyclone DDS's own
        # headers are <dds/...>, so that prefix is theirs in angle brackets).
        set(target "${CMAKE_MATCH_1}")
        if(target MATCHES "^dds/")
          continue()
        endif()
      else()
        continue()
      endif()
      if(target MATCHES "\\.\\./")
        string(APPEND violations "  ${rel}:${line_no}: includes \"${target}\" (no climbing out of the folder: name the layer)\n")
        continue()
      endif()
      if(NOT target MATCHES "^([^/]+)/")
        continue()
      endif()
      set(prefix "${CMAKE_MATCH_1}")
      if(prefix IN_LIST project_prefixes AND NOT prefix IN_LIST allowed)
        string(REPLACE ";" ", " allowed_text "${allowed}")
        string(APPEND violations "  ${rel}:${line_no}: includes \"${target}\"; ${folder} may include only ${allowed_text}\n")
        continue()
      endif()
      # A room of the estimation library including another room.
      set(from_room "")
      set(to_room "")
      if(folder STREQUAL "service/estimation" AND rel MATCHES "^service/estimation/([^/]+)/")
        set(from_room "${CMAKE_MATCH_1}")
      endif()
      if(target MATCHES "^estimation/([^/]+)/")
        set(to_room "${CMAKE_MATCH_1}")
      endif()
      if(from_room AND NOT from_room IN_LIST estimation_rooms)
        string(APPEND violations "  ${rel}:${line_no}: estimation/${from_room} is no room the check knows: "
                                 "add it to estimation_rooms and room_rules (cmake/check_layers.cmake)\n")
        continue()
      endif()
      if(from_room AND to_room AND NOT to_room IN_LIST estimation_rooms)
        string(APPEND violations "  ${rel}:${line_no}: includes \"${target}\", in no room the check knows\n")
        continue()
      endif()
      if(from_room AND to_room AND NOT from_room STREQUAL to_room)
        set(room_allowed "")
        foreach(room_rule IN LISTS room_rules)
          if(room_rule MATCHES "^${from_room}:(.*)$")
            string(REPLACE "," ";" room_allowed "${CMAKE_MATCH_1}")
          endif()
        endforeach()
        if(NOT to_room IN_LIST room_allowed)
          string(REPLACE ";" ", " room_text "${room_allowed}")
          if(room_text STREQUAL "")
            set(room_text "no other room")
          endif()
          string(APPEND violations
                 "  ${rel}:${line_no}: includes \"${target}\"; estimation/${from_room} may include only ${room_text}\n")
        endif()
      endif()
    endforeach()
  endforeach()
endforeach()

if(files_checked EQUAL 0)
  message(FATAL_ERROR "check_layers: no source files under ${SOURCE_DIR} (wrong SOURCE_DIR?)")
endif()
if(violations)
  message(FATAL_ERROR "check_layers: includes that break the layering (docs/architecture.md):\n${violations}")
endif()
message(STATUS "check_layers: ${files_checked} files keep to their layers")
