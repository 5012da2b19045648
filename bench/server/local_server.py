"""A real locaid-server on 127.0.0.1 for the bench/server scripts.

    with LocalServer(binary, tmp, ["--max-sessions", "32"]) as server:
        stub = rpc.LocalizationStub(grpc.insecure_channel(server.address))

Starts `binary --listen 127.0.0.1:0 --port-file ... --work-dir TMP/work` plus
the extra flags, logs to TMP/server.log, waits (up to 30 s) for the port, and
on exit sends SIGTERM (SIGKILL after 30 s). Exits the script with the log's
path when the server dies before listening.
"""
import os
import signal
import subprocess
import sys
import time


class LocalServer:
    def __init__(self, binary, tmp, extra_args=()):
        self.binary, self.tmp, self.extra_args = binary, tmp, list(extra_args)
        self.process, self.address, self.log = None, None, None

    def __enter__(self):
        port_file = os.path.join(self.tmp, "port")
        self.log = open(os.path.join(self.tmp, "server.log"), "w")
        self.process = subprocess.Popen([self.binary, "--listen", "127.0.0.1:0", "--port-file", port_file,
                                         "--work-dir", os.path.join(self.tmp, "work")] + self.extra_args,
                                        stdout=self.log, stderr=self.log)
        for _ in range(3000):
            if os.path.exists(port_file) and os.path.getsize(port_file) > 0:
                break
            if self.process.poll() is not None:
                self.__exit__(None, None, None)
                sys.exit(f"locaid-server exited with {self.process.returncode}; log in {self.log.name}")
            time.sleep(0.01)
        with open(port_file) as f:
            self.address = f"127.0.0.1:{int(f.read())}"
        return self

    def __exit__(self, *exc):
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.log.close()
        return False
