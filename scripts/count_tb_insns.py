#!/usr/bin/python3
"""Sums the guest instructions executed in a qemu-user log written with -d in_asm,exec,nochain
(scripts/bench_aarch64.sh). Reads the log on stdin, prints one integer.

in_asm blocks start with "IN: [symbol]" and list one instruction per line ("0x<pc>:  <hex>  <mnemonic>");
exec lines are "Trace <cpu>: <host ptr> [<cs_base>/<pc>/<flags>/<cflags>] <symbol>". With nochain every
executed block is logged, so the count is the sum over exec lines of the instruction count of the block
that starts at that pc (the last translation of it, if it was translated again).
"""
import sys


def main():
    insns = {}  # block start pc -> instructions
    total = 0
    block_pc = None
    block_n = 0
    unknown = 0
    for line in sys.stdin.buffer:
        if line.startswith(b"Trace "):
            if block_pc is not None:
                insns[block_pc] = block_n
                block_pc = None
            lb = line.find(b"[")
            fields = line[lb + 1:line.find(b"]", lb)].split(b"/")
            pc = int(fields[1], 16)
            n = insns.get(pc)
            if n is None:
                unknown += 1
            else:
                total += n
        elif line.startswith(b"IN:"):
            if block_pc is not None:
                insns[block_pc] = block_n
            block_pc = None
            block_n = 0
        elif line.startswith(b"0x"):
            colon = line.find(b":")
            if colon > 0:
                if block_n == 0:
                    block_pc = int(line[2:colon], 16)
                block_n += 1
        elif not line.strip():
            if block_pc is not None:
                insns[block_pc] = block_n
                block_pc = None
    if unknown:
        sys.stderr.write("count_tb_insns: %d executed blocks without a translation in the log\n" % unknown)
    print(total)


if __name__ == "__main__":
    main()
