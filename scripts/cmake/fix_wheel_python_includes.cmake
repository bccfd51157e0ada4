# Passed as -DCMAKE_PROJECT_INCLUDE=... by scripts/setup.sh when building an interface package
# against the ROS 2 Jazzy PyPI wheels. Not needed (nor used) with colcon on an apt install.
#
# Defect worked around: each message wheel exports <pkg>::<pkg>__rosidl_generator_py with
# INTERFACE_INCLUDE_DIRECTORIES of the machine that built the wheel
# (/opt/python/cp3XX-cp3XX/include/python3.X and .../site-packages/numpy/_core/include).
# At the end of the top-level CMakeLists.txt (deferred call), rewrite those paths of every imported
# target to the local Python and NumPy include directories. Generator expressions are evaluated
# at generate time, so changing the property at the end of configure is enough.

if(COMMAND cmake_language)
  if(NOT Python3_EXECUTABLE)
    message(FATAL_ERROR "fix_wheel_python_includes: set -DPython3_EXECUTABLE=<venv>/bin/python")
  endif()
  execute_process(
    COMMAND "${Python3_EXECUTABLE}" -c
      "import sysconfig, numpy; print(sysconfig.get_paths()['include'] + ';' + numpy.get_include(), end='')"
    OUTPUT_VARIABLE _pam_fix_includes
    RESULT_VARIABLE _pam_fix_rc)
  if(NOT _pam_fix_rc EQUAL 0)
    message(FATAL_ERROR "fix_wheel_python_includes: cannot query Python/NumPy include dirs from ${Python3_EXECUTABLE}")
  endif()
  list(GET _pam_fix_includes 0 PAM_FIX_PYTHON_INCLUDE_DIR)
  list(GET _pam_fix_includes 1 PAM_FIX_NUMPY_INCLUDE_DIR)

  function(_pam_fix_wheel_includes_in_dir dir)
    get_property(_targets DIRECTORY "${dir}" PROPERTY IMPORTED_TARGETS)
    foreach(_t IN LISTS _targets)
      if(NOT TARGET ${_t})
        continue()
      endif()
      get_target_property(_incs ${_t} INTERFACE_INCLUDE_DIRECTORIES)
      if(_incs AND _incs MATCHES "/opt/python/")
        set(_new "")
        foreach(_inc IN LISTS _incs)
          if(_inc MATCHES "^/opt/python/.*/numpy/")
            list(APPEND _new "${PAM_FIX_NUMPY_INCLUDE_DIR}")
          elseif(_inc MATCHES "^/opt/python/.*/include/python3")
            list(APPEND _new "${PAM_FIX_PYTHON_INCLUDE_DIR}")
          elseif(_inc MATCHES "^/opt/python/")
            # some other path of the wheel-building machine: drop it
          else()
            list(APPEND _new "${_inc}")
          endif()
        endforeach()
        list(REMOVE_DUPLICATES _new)
        set_target_properties(${_t} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_new}")
      endif()
    endforeach()
    get_property(_subdirs DIRECTORY "${dir}" PROPERTY SUBDIRECTORIES)
    foreach(_sub IN LISTS _subdirs)
      _pam_fix_wheel_includes_in_dir("${_sub}")
    endforeach()
  endfunction()

  function(_pam_fix_wheel_includes)
    _pam_fix_wheel_includes_in_dir("${CMAKE_SOURCE_DIR}")
  endfunction()

  # Only once, for the top-level project.
  if(CMAKE_CURRENT_SOURCE_DIR STREQUAL CMAKE_SOURCE_DIR AND NOT _PAM_FIX_WHEEL_INCLUDES_DEFERRED)
    set(_PAM_FIX_WHEEL_INCLUDES_DEFERRED TRUE)
    cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _pam_fix_wheel_includes)
  endif()
else()
  message(FATAL_ERROR "fix_wheel_python_includes: needs CMake >= 3.19 (cmake_language DEFER)")
endif()
