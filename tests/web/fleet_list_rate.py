#!/usr/bin/env python3
# Requests per second of GET /api/fleet against a running fleetgw serve, and the server's CPU time.
# Usage: fleet_list_rate.py PORT SERVER_PID CLIENTS SECONDS NAME PASSWORD [PATH] (docs/console.md);
# PATH defaults to /api/fleet.
import http.client, json, sys, threading, time, os
port, pid, clients, seconds = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
path = sys.argv[7] if len(sys.argv) > 7 else '/api/fleet'
c = http.client.HTTPConnection('127.0.0.1', port)
c.request('POST', '/api/login', json.dumps({'name': sys.argv[5], 'password': sys.argv[6]}), {'Content-Type': 'application/json'})
r = c.getresponse(); r.read()
cookie = r.getheader('Set-Cookie').split(';')[0]
def cpu():
    f = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf('SC_CLK_TCK')
counts = [0] * clients; size = [0]
def run(i):
    conn = http.client.HTTPConnection('127.0.0.1', port)
    end = time.time() + seconds
    while time.time() < end:
        conn.request('GET', path, headers={'Cookie': cookie})
        resp = conn.getresponse(); body = resp.read()
        assert resp.status == 200
        size[0] = len(body); counts[i] += 1
c0 = cpu(); t0 = time.time()
ts = [threading.Thread(target=run, args=(i,)) for i in range(clients)]
[t.start() for t in ts]; [t.join() for t in ts]
dt = time.time() - t0; dc = cpu() - c0
n = sum(counts)
print(f'{n} requests in {dt:.1f} s: {n/dt:.1f} req/s, {size[0]} bytes each, server CPU {dc:.2f} s ({1000*dc/n:.1f} ms per request)')
