#!/usr/bin/env python3
"""Lists the functions longer than a limit (default 120 lines) under the given folders.

A heuristic for the tree's Google style, not a parser: a definition's body opens with '{' at the
end of a line that starts in column 0 (namespaces do not indent) and closes with '}' in column 0.
It finds free functions and out-of-class member definitions; a function defined inside a class
body is not seen. docs/contributing.md ("Size and placement") says why the limit exists.

  tools/long-functions.py clients services          # functions over 120 lines
  tools/long-functions.py --limit 100 libs/mapping  # over 100
Exits 1 when it lists any, so a script can gate on it.
"""
import argparse
import os
import re
import sys

NOT_FUNCTIONS = ('namespace', 'struct', 'class', 'enum', 'extern', 'union')


def long_functions(root, limit):
    for folder, _, files in os.walk(root):
        for name in files:
            if not name.endswith(('.cc', '.h')):
                continue
            path = os.path.join(folder, name)
            with open(path, errors='replace') as f:
                lines = f.read().split('\n')
            i = 0
            while i < len(lines):
                line = lines[i]
                opens = (line and not line[0].isspace() and line.rstrip().endswith('{') and
                         '(' in ''.join(lines[max(0, i - 4):i + 1]) and
                         not line.startswith(NOT_FUNCTIONS) and
                         '=' not in line.split('(')[0])
                if opens:
                    j = i + 1
                    while j < len(lines) and not lines[j].startswith('}'):
                        j += 1
                    length = j - i + 1
                    if length > limit:
                        k = i
                        while k > 0 and '(' not in lines[k]:
                            k -= 1
                        yield length, path, i + 1, lines[k].strip()[:90]
                    i = j
                i += 1


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--limit', type=int, default=120, help='longest allowed, in lines')
    parser.add_argument('folders', nargs='+')
    args = parser.parse_args()
    found = []
    for folder in args.folders:
        if not os.path.isdir(folder):
            print(f'long-functions: {folder}: no such folder', file=sys.stderr)
            return 2
        found.extend(long_functions(folder, args.limit))
    for length, path, line, name in sorted(found, reverse=True):
        print(f'{length:5d} {path}:{line} {name}')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main())
