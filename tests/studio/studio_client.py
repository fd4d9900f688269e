"""A small WebSocket client (RFC 6455) and a studio launcher for the studio's tests.

Written out rather than taken from a package, because the tests send what no library sends on
purpose: fragments, binary and oversized messages, a foreign Origin, a socket closed mid-run.
"""
import base64
import json
import os
import re
import select
import socket
import struct
import subprocess
import time
import urllib.parse


def start_studio(cli, target, *extra):
    """Starts `flockmorph studio TARGET --port 0 --no-browser`; returns (process, address)."""
    proc = subprocess.Popen([cli, "studio", target, "--port", "0", "--no-browser", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline:
        line = proc.stdout.readline()
        if not line:
            raise RuntimeError("studio ended: " + proc.stderr.read())
        m = re.search(r"open (http://\S+)", line)
        if m:
            return proc, m.group(1)
    raise RuntimeError("studio printed no address")


def stop_studio(proc):
    proc.terminate()
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    return proc.returncode, err


def http_get(url, headers=None):
    """(status, body) of a GET, with any headers."""
    u = urllib.parse.urlsplit(url)
    s = socket.create_connection((u.hostname, u.port), timeout=10)
    lines = [f"GET {u.path or '/'} HTTP/1.1", f"Host: {u.netloc}", "Connection: close"]
    lines += [f"{k}: {v}" for k, v in (headers or {}).items()]
    s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    data = b""
    while True:
        chunk = s.recv(65536)
        if not chunk:
            break
        data += chunk
    s.close()
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split()[1]), body


class WebSocket:
    def __init__(self, url, origin=None, path="ws"):
        u = urllib.parse.urlsplit(url)
        self.sock = socket.create_connection((u.hostname, u.port), timeout=30)
        key = base64.b64encode(os.urandom(16)).decode()
        lines = [f"GET {u.path}{path} HTTP/1.1", f"Host: {u.netloc}", "Upgrade: websocket",
                 "Connection: Upgrade", f"Sec-WebSocket-Key: {key}", "Sec-WebSocket-Version: 13"]
        if origin:
            lines.append(f"Origin: {origin}")
        self.sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                break
            head += chunk
        m = re.search(rb"\b([1-5]\d\d)\b", head)
        self.status = int(m.group(1)) if m else 0  # 0: closed without an answer
        self.buffer = b""

    def send_frame(self, opcode, payload, fin=True):
        mask = os.urandom(4)
        n = len(payload)
        head = bytes([(0x80 if fin else 0) | opcode])
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 65536:
            head += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack(">Q", n)
        body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload)) if n < 1 << 20 else _mask_fast(payload, mask)
        self.sock.sendall(head + mask + body)

    def send(self, obj):
        self.send_frame(1, json.dumps(obj).encode())

    def _read(self, n):
        while len(self.buffer) < n:
            chunk = self.sock.recv(1 << 20)
            if not chunk:
                raise ConnectionError("closed")
            self.buffer += chunk
        out, self.buffer = self.buffer[:n], self.buffer[n:]
        return out

    def recv(self):
        """(opcode, payload) of the next message."""
        b0, b1 = self._read(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._read(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._read(8))[0]
        return b0 & 0x0F, self._read(n)

    def recv_json(self, type_=None, timeout=30):
        """The next text message (of `type_`, skipping others such as status)."""
        deadline = time.time() + timeout
        while time.time() < deadline:
            op, payload = self.recv()
            if op == 1:
                m = json.loads(payload)
                if type_ is None or m.get("type") == type_:
                    return m
        raise TimeoutError(f"no {type_} message")

    def wait_status(self, pred, timeout=60):
        deadline = time.time() + timeout
        while time.time() < deadline:
            m = self.recv_json("status", timeout=deadline - time.time())
            if pred(m):
                return m
        raise TimeoutError("status never matched")

    def frame(self, k):
        """Frame k's message: (header dict, {attribute id: bytes})."""
        self.send({"type": "frame", "k": k})
        while True:
            op, payload = self.recv()
            if op == 2:
                return parse_frame(payload)
            if op == 1 and json.loads(payload).get("type") == "error":
                raise RuntimeError(json.loads(payload)["message"])

    def readable(self, timeout):
        return bool(self.buffer) or bool(select.select([self.sock], [], [], timeout)[0])

    def close(self):
        self.sock.close()


def _mask_fast(payload, mask):
    import numpy as np
    a = np.frombuffer(payload, dtype=np.uint8)
    m = np.resize(np.frombuffer(mask, dtype=np.uint8), a.size)
    return (a ^ m).tobytes()


def parse_frame(payload):
    """docs/studio.md, "Frames": the header and each attribute's bytes."""
    magic, generation, frame, agents, count = struct.unpack_from("<4sIIII", payload, 0)
    assert magic == b"FMF1", magic
    attrs = {}
    for i in range(count):
        attr, offset, size = struct.unpack_from("<III", payload, 20 + 12 * i)
        attrs[attr] = payload[offset:offset + size]
    return {"generation": generation, "frame": frame, "agents": agents}, attrs
