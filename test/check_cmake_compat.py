#!/usr/bin/env python3
"""The package's CMake files ask only for what a ROS Noetic build has: CMake 3.16 (Ubuntu 20.04) and
upstream catkin 0.8 (docs/PACKAGING.md). This machine has CMake 3.25 and Debian's patched catkin, so a
build here cannot show it; this reads the files instead:

- cmake_minimum_required asks for 3.16 at most; no command, keyword, generator expression, variable or
  property that came after CMake 3.16 (the table NEWER, with the version that brought each);
  cmake_policy(SET) of a policy after 3.16 only under if(POLICY ...);
- no GTest:: imported targets (CMake >= 3.20's FindGTest; Debian's catkin uses them, upstream catkin
  gives GTEST_LIBRARIES and builds gtest from source);
- -Werror only under if(LIDAR_DESKEW_WERROR) (off by default: another compiler's warnings must not break
  a user's build);
- CMAKE_BUILD_TYPE never written to the cache (it would reach every package after ours in a workspace);
- find_package of the test-only packages (roslaunch, rostest, rviz, Qt5) only in test/CMakeLists.txt,
  which is read only with CATKIN_ENABLE_TESTING.

Usage: check_cmake_compat.py SOURCE_DIR   (prints each finding; exit status 0 when there is none)
"""
import os
import re
import sys

# (regex on the comment-free text, CMake version that brought it)
NEWER = [
    (r"\bcmake_path\s*\(", "3.20"),
    (r"\bcmake_language\s*\(", "3.18"),
    (r"\b(end)?block\s*\(", "3.25"),
    (r"\breturn\s*\(\s*PROPAGATE\b", "3.25"),
    (r"\bfile\s*\(\s*(ARCHIVE_CREATE|ARCHIVE_EXTRACT|CONFIGURE)\b", "3.18"),
    (r"\bfile\s*\(\s*(REAL_PATH|CHMOD|CHMOD_RECURSE)\b", "3.19"),
    (r"\bstring\s*\(\s*JSON\b", "3.19"),
    (r"\bforeach\s*\([^)]*\bZIP_LISTS\b", "3.17"),
    (r"\bmessage\s*\(\s*CHECK_(START|PASS|FAIL)\b", "3.17"),
    (r"\bfind_(program|library|path|file)\s*\([^)]*\bREQUIRED\b", "3.18"),
    (r"\bexecute_process\s*\([^)]*\bCOMMAND_ERROR_IS_FATAL\b", "3.19"),
    (r"\bexecute_process\s*\([^)]*\bECHO_(OUTPUT|ERROR)_VARIABLE\b", "3.18"),
    (r"\badd_subdirectory\s*\([^)]*\bSYSTEM\b", "3.25"),
    (r"\bfind_package\s*\([^)]*\bGLOBAL\b", "3.24"),
    (r"\btarget_sources\s*\([^)]*\bFILE_SET\b", "3.23"),
    (r"\bif\s*\([^)]*\bPATH_EQUAL\b", "3.24"),
    (r"\badd_custom_command\s*\([^)]*\bDEPFILE\b", "3.20 (Makefiles)"),
    (r"\$<LINK_LANGUAGE\b", "3.18"),
    (r"\$<DEVICE_LINK\b", "3.18"),
    (r"\$<TARGET_RUNTIME_DLLS\b", "3.21"),
    (r"\$<(LINK_LIBRARY|LINK_GROUP|PATH|PATH_EQUAL)\b", "3.24"),
    (r"\$<(LIST|COMPILE_ONLY)\b", "3.27"),
    (r"\bCMAKE_CURRENT_FUNCTION", "3.17"),
    (r"\bCMAKE_MESSAGE_CONTEXT\b", "3.17"),
    (r"\bCMAKE_CTEST_ARGUMENTS\b", "3.17"),
    (r"\bENVIRONMENT_MODIFICATION\b", "3.22"),
    (r"\b(CMAKE_)?COMPILE_WARNING_AS_ERROR\b", "3.24"),
    (r"\bGTest::", "3.20 (FindGTest's targets; upstream catkin has none)"),
]
LAST_POLICY_316 = 97  # CMP0097 is CMake 3.16's last policy
TEST_ONLY = ("roslaunch", "rostest", "rviz", "Qt5")


def cmake_files(root):
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and d not in ("build", "Testing"))
        for name in sorted(files):
            if name == "CMakeLists.txt" or name.endswith(".cmake"):
                yield os.path.join(folder, name)


def strip_comments(text):
    """The text with # comments blanked (quoted strings and [[...]] kept), lines kept."""
    out, quoted = [], False
    for line in text.split("\n"):
        kept = []
        for ch in line:
            if ch == '"':
                quoted = not quoted
            elif ch == "#" and not quoted:
                break
            kept.append(ch)
        out.append("".join(kept))
    return "\n".join(out)


def line_of(text, offset):
    return text.count("\n", 0, offset) + 1


def conditions_at(text):
    """For each line, the list of open if() conditions (innermost last)."""
    stack, per_line = [], []
    for line in text.split("\n"):
        per_line.append(list(stack))
        m = re.match(r"\s*(if|elseif|else|endif)\s*\((.*)\)\s*$", line)
        if not m:
            continue
        word, cond = m.group(1), m.group(2).strip()
        if word == "if":
            stack.append(cond)
        elif word in ("elseif", "else") and stack:
            stack[-1] = "NOT (%s)" % stack[-1] if word == "else" else cond
        elif word == "endif" and stack:
            stack.pop()
    return per_line


def check(root):
    findings = []
    for path in cmake_files(root):
        rel = os.path.relpath(path, root)
        code = strip_comments(open(path).read())
        conds = conditions_at(code)

        def report(offset, what):
            findings.append("%s:%d: %s" % (rel, line_of(code, offset), what))

        for pattern, version in NEWER:
            for m in re.finditer(pattern, code, re.S):
                report(m.start(), "%r needs CMake %s" % (m.group(0).strip(), version))
        for m in re.finditer(r"\bcmake_minimum_required\s*\(\s*VERSION\s+(\d+)\.(\d+)", code):
            if (int(m.group(1)), int(m.group(2))) > (3, 16):
                report(m.start(), "cmake_minimum_required asks for %s.%s (Noetic has 3.16)" % m.groups())
        for m in re.finditer(r"\bcmake_policy\s*\(\s*SET\s+CMP(\d{4})", code):
            number = int(m.group(1))
            guard = "POLICY CMP%04d" % number
            if number > LAST_POLICY_316 and not any(guard in c for c in conds[line_of(code, m.start()) - 1]):
                report(m.start(), "policy CMP%04d is newer than CMake 3.16: set it under if(%s)" % (number, guard))
        for m in re.finditer(r"-Werror\b", code):
            if not any(re.search(r"\bLIDAR_DESKEW_WERROR\b", c) and not c.startswith("NOT")
                       for c in conds[line_of(code, m.start()) - 1]):
                report(m.start(), "-Werror outside if(LIDAR_DESKEW_WERROR)")
        for m in re.finditer(r"\bset\s*\(\s*CMAKE_BUILD_TYPE\b[^)]*\bCACHE\b", code):
            report(m.start(), "CMAKE_BUILD_TYPE written to the cache")
        if rel != os.path.join("test", "CMakeLists.txt"):
            for m in re.finditer(r"\b(?:find_package|set)\s*\(([^)]*)\)", code):
                if m.group(0).startswith("set") and "COMPONENTS" not in m.group(1).split()[0]:
                    continue
                words = m.group(1).split()
                for name in TEST_ONLY:
                    if name in words:
                        report(m.start(), "find_package of the test-only %s outside test/CMakeLists.txt" % name)
    return findings


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "."
    files = list(cmake_files(root))
    findings = check(root)
    for finding in findings:
        print(finding)
    print("%d CMake files (%s) against CMake 3.16 and upstream catkin 0.8: %d findings"
          % (len(files), " ".join(os.path.relpath(f, root) for f in files), len(findings)))
    return 1 if findings or not files else 0


if __name__ == "__main__":
    sys.exit(main())
