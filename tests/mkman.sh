#!/bin/sh
# Generate a program's manual page from the same source as its --help.
exec "$1" --help-man
