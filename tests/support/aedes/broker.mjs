// A plain-TCP aedes broker on 127.0.0.1:PORT for the tests (aedes-broker.sh starts it). One line
// per event on stdout, so a test can wait on "listening", "subscribe <client> <filter>" and
// "publish <client> <topic> <bytes>" instead of sleeping. Topics and client ids come from the
// network: they are printed JSON-quoted so a hostile one cannot forge a line.
import { Aedes } from 'aedes'
import serverFactory from 'aedes-server-factory'

const port = Number(process.argv[2])
if (!Number.isInteger(port) || port <= 0 || port > 65535) {
  console.error(`usage: broker.mjs PORT (got ${JSON.stringify(process.argv[2])})`)
  process.exit(2)
}
const q = (s) => JSON.stringify(String(s))
const aedes = await Aedes.createBroker()
aedes.on('client', (c) => console.log(`connect ${q(c.id)}`))
aedes.on('clientDisconnect', (c) => console.log(`disconnect ${q(c.id)}`))
aedes.on('subscribe', (subs, c) => {
  for (const s of subs) console.log(`subscribe ${q(c ? c.id : '')} ${q(s.topic)}`)
})
aedes.on('publish', (p, c) => {
  if (c) console.log(`publish ${q(c.id)} ${q(p.topic)} ${p.payload.length}`)
})
const server = serverFactory.createServer(aedes)
server.listen(port, '127.0.0.1', () => console.log(`listening ${port}`))
const stop = () => server.close(() => aedes.close(() => process.exit(0)))
process.on('SIGTERM', stop)
process.on('SIGINT', stop)
