"""``python -m msg_adapters [--ros-args ...]`` runs the contact_sim node."""
import sys

from .launch import main

if __name__ == "__main__":
    sys.exit(main())
